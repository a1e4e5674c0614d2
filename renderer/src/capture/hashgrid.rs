//! The probabilistic hash grid of environment samples (Rohmer et al., Sec. 5): a fixed number of
//! slots addressed by hashing a sample's virtual cell (0.05 m in the paper); a sample whose slot
//! is taken replaces the occupant with probability 1 / (the slot's insertions so far), so every
//! sample ever offered to a slot is equally likely to be the one it holds (reservoir sampling),
//! whatever the order. Samples are removed when a later depth image sees through them.

use crate::math::{Rng, hash3};
use glam::{IVec3, Vec3};

/// One captured point of the real environment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvironmentSample {
    pub position: Vec3,
    pub normal: Vec3,
    /// Linear RGB radiance seen by the colour camera.
    pub colour: Vec3,
    /// The capture pose that made it.
    pub pose: u32,
}

impl EnvironmentSample {
    /// The sample's unit normal, or None where the capture left none usable (not finite, or
    /// too short to be a fitted plane's normal): the splats then fall back on a disk facing the
    /// impostor's centre or a ball.
    pub fn unit_normal(&self) -> Option<Vec3> {
        (self.normal.is_finite() && self.normal.length_squared() > 0.5).then(|| self.normal.normalize())
    }
}

#[derive(Clone, Debug)]
pub struct HashGrid {
    pub cell: f32,
    slots: Vec<Option<EnvironmentSample>>,
    /// Insertions per slot since it was created (the replacement rule's counter).
    insertions: Vec<u32>,
}

/// What an insertion did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inserted {
    /// Into an empty slot.
    New,
    /// Replaced the slot's occupant.
    Replaced,
    /// Kept the occupant; the sample was dropped.
    Dropped,
}

impl HashGrid {
    /// A grid of `capacity` slots (≥ 1) and virtual cells of `cell` metres.
    pub fn new(capacity: usize, cell: f32) -> HashGrid {
        let capacity = capacity.max(1);
        HashGrid { cell, slots: vec![None; capacity], insertions: vec![0; capacity] }
    }

    pub fn capacity(&self) -> usize {
        self.slots.len()
    }

    /// The virtual cell of a position.
    pub fn cell_of(&self, p: Vec3) -> IVec3 {
        (p / self.cell).floor().as_ivec3()
    }

    fn slot(&self, p: Vec3) -> usize {
        let c = self.cell_of(p);
        (hash3(c.x as u32 as u64, c.y as u32 as u64, c.z as u32 as u64) % self.slots.len() as u64) as usize
    }

    /// Offers a sample to its slot (the replacement rule above).
    pub fn insert(&mut self, sample: EnvironmentSample, rng: &mut Rng) -> Inserted {
        let i = self.slot(sample.position);
        self.insertions[i] = self.insertions[i].saturating_add(1);
        match self.slots[i] {
            None => {
                self.slots[i] = Some(sample);
                Inserted::New
            }
            Some(_) if rng.next_f32() * (self.insertions[i] as f32) < 1.0 => {
                self.slots[i] = Some(sample);
                Inserted::Replaced
            }
            Some(_) => Inserted::Dropped,
        }
    }

    /// Removes every sample `keep` refuses; returns how many.
    pub fn retain(&mut self, mut keep: impl FnMut(&EnvironmentSample) -> bool) -> usize {
        let mut removed = 0;
        for slot in &mut self.slots {
            if slot.as_ref().is_some_and(|s| !keep(s)) {
                *slot = None;
                removed += 1;
            }
        }
        removed
    }

    pub fn samples(&self) -> impl Iterator<Item = &EnvironmentSample> {
        self.slots.iter().flatten()
    }

    pub fn len(&self) -> usize {
        self.slots.iter().filter(|s| s.is_some()).count()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f32, pose: u32) -> EnvironmentSample {
        EnvironmentSample { position: Vec3::new(x, 0.01, 0.01), normal: Vec3::Y, colour: Vec3::ONE, pose }
    }

    #[test]
    fn every_sample_offered_to_a_slot_is_kept_with_equal_probability() {
        // five samples in one 5 cm cell, offered in the same order 20 000 times: each survives
        // with probability 1/5; a chi-square test on the survivors' counts (4 degrees of
        // freedom, critical value 18.47 at α = 0.001)
        let trials = 20_000;
        let mut kept = [0u32; 5];
        let mut rng = Rng::new(9);
        for _ in 0..trials {
            let mut grid = HashGrid::new(64, 0.05);
            for k in 0..5 {
                grid.insert(sample(0.001 * k as f32, k), &mut rng);
            }
            let s: Vec<_> = grid.samples().collect();
            assert_eq!(s.len(), 1);
            kept[s[0].pose as usize] += 1;
        }
        let expected = trials as f64 / 5.0;
        let chi2: f64 = kept.iter().map(|&k| (k as f64 - expected).powi(2) / expected).sum();
        assert!(chi2 < 18.47, "survivors {kept:?}, chi-square {chi2:.1}");
    }

    #[test]
    fn separate_cells_keep_their_samples_and_removal_counts() {
        let mut grid = HashGrid::new(1 << 12, 0.05);
        let mut rng = Rng::new(1);
        for k in 0..10 {
            assert_eq!(grid.insert(sample(0.1 * k as f32, k), &mut rng), Inserted::New);
        }
        assert_eq!(grid.len(), 10);
        assert_eq!(grid.retain(|s| s.pose % 2 == 0), 5);
        assert_eq!(grid.len(), 5);
        // a slot emptied by removal takes the next sample whatever its counter
        assert_eq!(grid.insert(sample(0.1, 11), &mut rng), Inserted::New);
    }
}
