//! A participant's task schedule: condition order and target positions, from the study and a
//! 64-bit seed (stored with the participant, together with every planned trial).
//!
//! Order: task by task in the study file's order; each task opens with its practice trials
//! (conditions taken in the participant's order, cyclically; not analysed), then one block per
//! condition in the participant's counterbalanced order (row `slot mod rows` of the Williams
//! design or Latin square, see [`super::williams`]), `trials_per_condition` trials each.
//! Positions are drawn until the virtual cube lies wholly in the camera's view (the layout's
//! `reach`, measured from the scene's camera at start-up; after [`MAX_DRAWS`] draws the last one
//! is clamped into reach). They come from ChaCha8 seeded with the participant seed (`seed_from_u64`, fixed by
//! rand_chacha's reproducibility guarantee); the draws are written out here, not taken from
//! `rand`'s distributions, so a stored seed keeps reproducing its schedule.

use crate::study::task::Condition;
use glam::DVec3;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use super::williams;
use crate::study::task::{Counterbalance, Directions, TaskKind, TaskStudy};
use crate::trial::PlannedTaskTrial;

/// Version of the task scheduling algorithm, stored with each participant.
pub const TASK_SCHEDULE_VERSION: i64 = 1;

/// Where the cubes are: the real cube's centre (metres, scene coordinates; the table top is
/// y = 0), the cubes' half height, and how far the virtual cube may go from the real one and
/// stay wholly in the camera's view: `reach` = [towards −x, +x, −z, +z] in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    pub real_centre: [f64; 3],
    pub half_height: f64,
    pub reach: [f64; 4],
}

impl Layout {
    /// Whether a centre is within `reach` of the real cube (in x and z).
    pub fn within_reach(&self, centre: DVec3) -> bool {
        let (dx, dz) = (centre.x - self.real_centre[0], centre.z - self.real_centre[2]);
        -self.reach[0] <= dx && dx <= self.reach[1] && -self.reach[2] <= dz && dz <= self.reach[3]
    }

    /// The nearest centre within reach (x and z clamped).
    pub fn clamp(&self, centre: DVec3) -> DVec3 {
        let r = self.real_centre;
        DVec3::new(
            centre.x.clamp(r[0] - self.reach[0], r[0] + self.reach[1]),
            centre.y,
            centre.z.clamp(r[2] - self.reach[2], r[2] + self.reach[3]),
        )
    }
}

/// Draws per position before giving up and clamping the last draw into reach.
pub const MAX_DRAWS: usize = 1000;

/// The condition order (indices into the study's conditions) of the participant in this
/// counterbalancing slot (the participant's `slot`, see [`super::store`]).
pub fn condition_order(study: &TaskStudy, slot: u64) -> Vec<usize> {
    let n = study.conditions.len();
    let design = match study.counterbalance {
        Counterbalance::Williams => williams::williams(n),
        Counterbalance::Latin => williams::latin(n),
    };
    design[(slot % design.len() as u64) as usize].clone()
}

struct Stream(ChaCha8Rng);

impl Stream {
    /// Uniform on [0, 1) with 53 random bits.
    fn unit(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    fn between(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }
    fn below(&mut self, bound: u64) -> u64 {
        // Lemire's method with rejection: uniform on 0..bound.
        loop {
            let product = (self.0.next_u64() as u128) * (bound as u128);
            if (product as u64) >= bound.wrapping_neg() % bound {
                return (product >> 64) as u64;
            }
        }
    }
    /// A unit direction in the table plane (x, z).
    fn direction(&mut self, directions: Directions) -> DVec3 {
        match directions {
            Directions::Main => [DVec3::X, -DVec3::X, DVec3::Z, -DVec3::Z][self.below(4) as usize],
            Directions::Any => {
                let angle = self.between(0.0, std::f64::consts::TAU);
                DVec3::new(angle.cos(), 0.0, angle.sin())
            }
        }
    }
}

/// The whole schedule of one participant (condition order from the counterbalancing `slot`).
pub fn plan(study: &TaskStudy, layout: &Layout, seed: u64, slot: u64) -> Vec<PlannedTaskTrial> {
    let mut stream = Stream(ChaCha8Rng::seed_from_u64(seed));
    let order = condition_order(study, slot);
    let real = DVec3::from(layout.real_centre);
    let mut trials = Vec::with_capacity(study.trial_count());
    for task in &study.tasks {
        let mut conditions: Vec<(Condition, bool)> =
            (0..study.practice as usize).map(|k| (study.conditions[order[k % order.len()]], true)).collect();
        for &index in &order {
            conditions
                .extend(std::iter::repeat_n((study.conditions[index], false), study.trials_per_condition as usize));
        }
        for (condition, practice) in conditions {
            // positions are drawn until the cube is wholly in view (rejection sampling)
            let mut draw = 0;
            let (start, target) = loop {
                draw += 1;
                let distance = stream.between(task.min_cm, task.max_cm) / 100.0;
                let (start, target) = match task.kind {
                    TaskKind::Distance => {
                        let at = real + stream.direction(task.directions) * distance;
                        (at, at)
                    }
                    TaskKind::Placement => (real + stream.direction(Directions::Any) * distance, real),
                    TaskKind::Contact => {
                        let beside = real + stream.direction(Directions::Any) * distance;
                        let height = stream.between(task.min_height_cm, task.max_height_cm) / 100.0;
                        (beside + DVec3::Y * height, beside)
                    }
                };
                if layout.within_reach(start) {
                    break (start, target);
                }
                if draw >= MAX_DRAWS {
                    let start = layout.clamp(start);
                    let target = if task.kind == TaskKind::Contact {
                        DVec3::new(start.x, target.y, start.z)
                    } else if task.kind == TaskKind::Distance {
                        start
                    } else {
                        target
                    };
                    break (start, target);
                }
            };
            trials.push(PlannedTaskTrial {
                trial: trials.len() as u32 + 1,
                task: task.name.clone(),
                kind: task.kind,
                condition,
                practice,
                start: start.to_array(),
                target: target.to_array(),
            });
        }
    }
    trials
}

#[cfg(test)]
mod tests {
    use super::*;
    use mrstudy_renderer::gpu::GiLevel;
    use std::path::Path;

    /// The test lab study with the thesis's three conditions, two trials per condition, one
    /// practice trial and all three tasks.
    fn study() -> TaskStudy {
        let text = crate::lab_study_fixture::LabStudy {
            conditions: &["none", "shadows", "gi"],
            trials_per_condition: 2,
            practice: 1,
            tasks: &["kind = \"distance\"", "kind = \"placement\"", "kind = \"contact\""],
            ..Default::default()
        }
        .toml();
        crate::study::task::parse(&text, Path::new("lab.toml"), Path::new("."), String::new()).unwrap()
    }

    const LAYOUT: Layout = Layout { real_centre: [0.0, 0.025, 0.0], half_height: 0.025, reach: [0.3; 4] };

    #[test]
    fn positions_stay_within_the_view() {
        let study = study();
        let layout = Layout { reach: [0.22, 0.25, 0.3, 0.1], ..LAYOUT };
        let mut towards_camera = 0;
        for seed in 0..50 {
            for trial in plan(&study, &layout, seed, seed) {
                let start = DVec3::from(trial.start);
                assert!(layout.within_reach(start), "{trial:?}");
                assert!(start.z <= 0.1 + 1e-12);
                towards_camera += (start.z > 0.05) as usize;
            }
        }
        assert!(towards_camera > 0, "positions towards the camera still occur where they fit");
    }

    #[test]
    fn a_schedule_is_reproducible_and_follows_the_counterbalanced_order() {
        let study = study();
        let first = plan(&study, &LAYOUT, 7, 4);
        assert_eq!(first, plan(&study, &LAYOUT, 7, 4));
        assert_ne!(first, plan(&study, &LAYOUT, 8, 4));
        assert_eq!(first.len(), study.trial_count());
        assert_eq!(first.len(), 3 * (1 + 3 * 2));
        // ordinal 4 of the six-row design for three conditions: [0, 2, 1]
        let order = condition_order(&study, 4);
        assert_eq!(order, vec![0, 2, 1]);
        let counted: Vec<Condition> =
            first.iter().filter(|t| t.task == "distance" && !t.practice).map(|t| t.condition).collect();
        assert_eq!(
            counted,
            vec![
                Condition::Dir(GiLevel::None),
                Condition::Dir(GiLevel::None),
                Condition::Dir(GiLevel::Gi),
                Condition::Dir(GiLevel::Gi),
                Condition::Dir(GiLevel::Shadows),
                Condition::Dir(GiLevel::Shadows)
            ]
        );
        assert!(first[0].practice && first[0].task == "distance");
        for (index, trial) in first.iter().enumerate() {
            assert_eq!(trial.trial as usize, index + 1);
        }
    }

    #[test]
    fn positions_respect_the_task_parameters() {
        let study = study();
        for seed in 0..50 {
            for trial in plan(&study, &LAYOUT, seed, seed) {
                let start = DVec3::from(trial.start);
                let real = DVec3::from(LAYOUT.real_centre);
                let planar = (start - real) * DVec3::new(1.0, 0.0, 1.0);
                match trial.kind {
                    TaskKind::Distance => {
                        assert!((0.08..=0.25).contains(&planar.length()), "{trial:?}");
                        // along a main axis
                        assert!(planar.x.abs() < 1e-12 || planar.z.abs() < 1e-12, "{trial:?}");
                        assert_eq!(trial.start, trial.target);
                    }
                    TaskKind::Placement => {
                        assert!((0.08..=0.20).contains(&planar.length()), "{trial:?}");
                        assert_eq!(trial.target, LAYOUT.real_centre);
                    }
                    TaskKind::Contact => {
                        let height = start.y - real.y;
                        assert!((0.01..=0.08).contains(&height), "{trial:?}");
                        assert_eq!(trial.target[1], LAYOUT.real_centre[1]);
                    }
                }
            }
        }
    }
}
