//! The one lab task study the tests use, small and fast by default (96×72 frames, two
//! photograph samples, 16 VPLs, one trial per condition, no practice), with the keys the tests
//! vary. Shared by the server's WebSocket tests, its unit tests of task study files and lab
//! plans (`crate::lab_study_fixture`), and the binary's end-to-end tests (included there by
//! `#[path]`).
// Each includer uses a different part of it.
#![allow(dead_code)]

/// A lab study for tests: `LabStudy { seed: 5, ..LabStudy::default() }.toml()`.
#[derive(Debug, Clone)]
pub struct LabStudy {
    pub title: &'static str,
    pub welcome: &'static str,
    pub instructions: &'static str,
    /// Rendering conditions (gi levels).
    pub conditions: &'static [&'static str],
    pub seed: u64,
    pub trials_per_condition: u32,
    pub practice: u32,
    /// `None`: the study file's default (300 ms).
    pub min_response_ms: Option<u32>,
    pub size: [u32; 2],
    pub photo_spp: u32,
    /// Each task as its TOML body (`kind = "placement"\nstep_cm = 1`).
    pub tasks: &'static [&'static str],
}

impl Default for LabStudy {
    fn default() -> Self {
        LabStudy {
            title: "Lab",
            welcome: "Hello.",
            instructions: "Do the tasks.",
            conditions: &["none", "gi"],
            seed: 5,
            trials_per_condition: 1,
            practice: 0,
            min_response_ms: Some(0),
            size: [96, 72],
            photo_spp: 2,
            tasks: &["kind = \"distance\"", "kind = \"placement\"\nstep_cm = 1"],
        }
    }
}

impl LabStudy {
    /// The study file (slug `lab`).
    pub fn toml(&self) -> String {
        let mut text = self.head();
        let conditions: Vec<String> = self.conditions.iter().map(|name| format!("\"{name}\"")).collect();
        text += &format!(
            "[design]\nconditions = [{}]\ntrials_per_condition = {}\npractice = {}\nseed = {}\n",
            conditions.join(", "),
            self.trials_per_condition,
            self.practice,
            self.seed
        );
        text += &format!(
            "[render]\nsize = [{}, {}]\nphoto_spp = {}\nvpls = 16\nshadow_map_size = 128\nenv_lights = 4\n",
            self.size[0], self.size[1], self.photo_spp
        );
        text + &self.task_tables()
    }

    /// The study file with only its required keys (and `min_response_ms` where set): the
    /// `[design]` and `[render]` tables left to their defaults.
    pub fn required_toml(&self) -> String {
        self.head() + &self.task_tables()
    }

    fn head(&self) -> String {
        let mut text = format!("slug = \"lab\"\ntitle = \"{}\"\nkind = \"task\"\n", self.title);
        if let Some(ms) = self.min_response_ms {
            text += &format!("min_response_ms = {ms}\n");
        }
        text + &format!("[texts]\nwelcome = \"{}\"\ninstructions = \"{}\"\n", self.welcome, self.instructions)
    }

    fn task_tables(&self) -> String {
        self.tasks.iter().map(|task| format!("[[tasks]]\n{task}\n")).collect()
    }
}
