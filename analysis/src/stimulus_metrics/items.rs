//! The items the perceived worth is fitted for: every stimulus (scene × condition) where the
//! trials name their scenes and every stimulus has metrics, else every condition with its
//! metrics averaged over its stimuli.

use std::collections::HashMap;

use crate::data::{Judgment, Judgments, TrialScenes};
use crate::design;

use super::{Level, Metric, MetricValues, Region, StimulusMetrics, StimulusRecord};

/// The items of a fit: their names and the judgments between them.
pub(super) struct Items {
    pub(super) level: Level,
    pub(super) scene: Vec<Option<String>>,
    pub(super) condition: Vec<String>,
    pub(super) values: Vec<MetricValues>,
    pub(super) rows: Vec<Judgment>,
}

impl Items {
    pub(super) fn label(&self, k: usize) -> String {
        match &self.scene[k] {
            Some(scene) => format!("{scene}/{}", self.condition[k]),
            None => self.condition[k].clone(),
        }
    }
}

/// Why the stimulus level cannot be used, or the stimulus items.
pub(super) fn stimulus_items(
    judgments: &Judgments,
    scenes: Option<&TrialScenes>,
    metrics: &StimulusMetrics,
) -> std::result::Result<Items, String> {
    let Some(scenes) = scenes else {
        return Err("the trials have no scene_left/scene_right columns".to_string());
    };
    let empty = scenes.rows.iter().filter(|pair| pair.contains(&TrialScenes::EMPTY)).count();
    if empty > 0 {
        return Err(format!("{empty} of {} trials have an empty scene_left or scene_right", scenes.rows.len()));
    }
    // Items sorted by scene name, then condition order.
    let mut keys: Vec<(u32, u32)> = judgments
        .rows
        .iter()
        .zip(&scenes.rows)
        .flat_map(|(row, pair)| [(pair[0], row.left), (pair[1], row.right)])
        .collect();
    keys.sort_by(|a, b| scenes.names[a.0 as usize].cmp(&scenes.names[b.0 as usize]).then(a.1.cmp(&b.1)));
    keys.dedup();
    let mut without = Vec::new();
    let mut values = Vec::with_capacity(keys.len());
    for &(scene, condition) in &keys {
        let (scene, condition) = (&scenes.names[scene as usize], &judgments.conditions[condition as usize]);
        match metrics.get(scene, condition) {
            Some(record) => values.push(record.values),
            None => without.push(format!("`{scene}/{condition}`")),
        }
    }
    if !without.is_empty() {
        let more = if without.len() > 3 { format!(" and {} more", without.len() - 3) } else { String::new() };
        let verb = if without.len() == 1 { "has" } else { "have" };
        return Err(format!(
            "the stimul{} {}{more} of the trials {verb} no metrics in the metrics CSV",
            if without.len() == 1 { "us" } else { "i" },
            without[..without.len().min(3)].join(", ")
        ));
    }
    let index: HashMap<(u32, u32), u32> = keys.iter().enumerate().map(|(k, &key)| (key, k as u32)).collect();
    let rows: Vec<Judgment> = judgments
        .rows
        .iter()
        .zip(&scenes.rows)
        .map(|(row, pair)| Judgment { left: index[&(pair[0], row.left)], right: index[&(pair[1], row.right)], ..*row })
        .collect();
    let items = Items {
        level: Level::Stimulus,
        scene: keys.iter().map(|&(s, _)| Some(scenes.names[s as usize].clone())).collect(),
        condition: keys.iter().map(|&(_, c)| judgments.conditions[c as usize].clone()).collect(),
        values,
        rows,
    };
    let pairs = design::tally(items.rows.iter().map(|row| (row.left, row.right, row.left_chosen, row.count)));
    let groups = design::components(keys.len(), &pairs).len();
    if groups > 1 {
        let same = scenes.rows.iter().all(|pair| pair[0] == pair[1]);
        let why = if same { " (every trial shows the same scene on both sides, scenes = \"same\")" } else { "" };
        return Err(format!("the {} stimuli form {groups} unconnected groups{why}", keys.len()));
    }
    Ok(items)
}

/// The condition items, with each metric averaged over the condition's stimuli, and how.
pub(super) fn condition_items(
    judgments: &Judgments,
    scenes: Option<&TrialScenes>,
    metrics: &StimulusMetrics,
) -> (Items, String) {
    let n = judgments.conditions.len();
    // The stimuli shown, where the trials say which.
    let shown: Option<Vec<Vec<&str>>> =
        scenes.filter(|s| !s.rows.iter().any(|p| p.contains(&TrialScenes::EMPTY))).map(|s| {
            let mut shown = vec![Vec::new(); n];
            for (row, pair) in judgments.rows.iter().zip(&s.rows) {
                for (condition, scene) in [(row.left, pair[0]), (row.right, pair[1])] {
                    shown[condition as usize].push(s.names[scene as usize].as_str());
                }
            }
            for list in &mut shown {
                list.sort_unstable();
                list.dedup();
            }
            shown
        });
    let mut values = Vec::with_capacity(n);
    for (c, condition) in judgments.conditions.iter().enumerate() {
        let records: Vec<&StimulusRecord> = match &shown {
            Some(shown) => shown[c].iter().filter_map(|scene| metrics.get(scene, condition)).collect(),
            None => metrics.of_condition(condition).collect(),
        };
        let mut mean: MetricValues = [[None; 3]; 8];
        for metric in Metric::ALL {
            for region in Region::ALL {
                let present: Vec<f64> = records.iter().filter_map(|r| r.value(metric, region)).collect();
                if !present.is_empty() {
                    // A convex combination of finite values: finite.
                    mean[metric.index()][region.index()] = Some(present.iter().map(|v| v / present.len() as f64).sum());
                }
            }
        }
        values.push(mean);
    }
    let averaging = match shown {
        Some(_) => {
            "each metric is the mean over the condition's stimuli shown in the trials that the metrics CSV has; a region missing for a stimulus (its mask empty) is averaged over the stimuli that have it"
        }
        None => {
            "each metric is the mean over all of the condition's stimuli in the metrics CSV (the trials do not say which were shown); a region missing for a stimulus (its mask empty) is averaged over the stimuli that have it"
        }
    };
    let items = Items {
        level: Level::Condition,
        scene: vec![None; n],
        condition: judgments.conditions.clone(),
        values,
        rows: judgments.rows.clone(),
    };
    (items, averaging.to_string())
}
