//! The one lab task study the tests use, small and fast by default (96×72 frames, two
//! photograph samples, 16 VPLs, one trial per condition, no practice), with the keys the tests
//! vary. Shared by the server's WebSocket tests and the binary's end-to-end tests (included
//! there by `#[path]`).

/// A lab study for tests: `LabStudy { seed: 5, ..LabStudy::default() }.toml()`.
#[derive(Debug, Clone)]
pub struct LabStudy {
    pub title: &'static str,
    pub welcome: &'static str,
    pub instructions: &'static str,
    /// Rendering conditions (gi levels).
    pub conditions: &'static [&'static str],
    pub seed: u64,
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
        let mut text = format!("slug = \"lab\"\ntitle = \"{}\"\nkind = \"task\"\n", self.title);
        if let Some(ms) = self.min_response_ms {
            text += &format!("min_response_ms = {ms}\n");
        }
        let conditions: Vec<String> = self.conditions.iter().map(|name| format!("\"{name}\"")).collect();
        text += &format!(
            "[texts]\nwelcome = \"{}\"\ninstructions = \"{}\"\n[design]\nconditions = [{}]\ntrials_per_condition = 1\npractice = 0\nseed = {}\n",
            self.welcome,
            self.instructions,
            conditions.join(", "),
            self.seed
        );
        text += &format!(
            "[render]\nsize = [{}, {}]\nphoto_spp = {}\nvpls = 16\nshadow_map_size = 128\nenv_lights = 4\n",
            self.size[0], self.size[1], self.photo_spp
        );
        for task in self.tasks {
            text += &format!("[[tasks]]\n{task}\n");
        }
        text
    }
}
