//! Knobs: the renderer settings a threshold study (`kind = "threshold"`) varies, each changing
//! exactly one setting of the GPU's differential instant radiosity or of the CPU path tracer,
//! everything else of the stimulus held as its study renders it.
//!
//! | knob | what it changes |
//! |---|---|
//! | `vpls` | the VPL budget of the `gi` condition (`DirParams::vpls`) |
//! | `ism_size` | each VPL's imperfect shadow map resolution (`DirParams::ism_size`; 0: unshadowed) |
//! | `ism_points` | points splatted into each imperfect shadow map (`DirParams::ism_points`) |
//! | `rsm_size` | each reflective shadow map's resolution, where VPLs are drawn (`DirParams::rsm_size`) |
//! | `shadow_map_size` | each light's shadow map resolution (`DirParams::shadow_map_size`) |
//! | `bounces` | bounces of indirect light (`DirParams::bounces`, 1–8) |
//! | `bounce_candidates` | points each multiple-bounce slot searches (`DirParams::bounce_candidates`) |
//! | `caustic_map_size` | each caustic map's resolution (`SpecularParams::caustic_map_size`) |
//! | `spp` | samples per pixel of a path-traced composite (CPU): the stimulus is the whole scene path-traced at this many samples, beside a ground truth at `[render] spp` |
//!
//! A [`KnobSetting`] is part of [`crate::stimulus::StimulusSettings`] and of its fingerprint;
//! the `vpls` knob sets the settings' own VPL budget instead, so a level equal to another
//! study's budget is the same stored stimulus.

use serde::{Deserialize, Serialize};

/// One renderer setting a threshold study varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Knob {
    Vpls,
    IsmSize,
    IsmPoints,
    RsmSize,
    ShadowMapSize,
    Bounces,
    BounceCandidates,
    CausticMapSize,
    Spp,
}

impl Knob {
    /// Every knob, in the order the documentation lists them.
    pub const ALL: [Knob; 9] = [
        Knob::Vpls,
        Knob::IsmSize,
        Knob::IsmPoints,
        Knob::RsmSize,
        Knob::ShadowMapSize,
        Knob::Bounces,
        Knob::BounceCandidates,
        Knob::CausticMapSize,
        Knob::Spp,
    ];

    /// The knob's name in a study file.
    pub fn name(self) -> &'static str {
        match self {
            Knob::Vpls => "vpls",
            Knob::IsmSize => "ism_size",
            Knob::IsmPoints => "ism_points",
            Knob::RsmSize => "rsm_size",
            Knob::ShadowMapSize => "shadow_map_size",
            Knob::Bounces => "bounces",
            Knob::BounceCandidates => "bounce_candidates",
            Knob::CausticMapSize => "caustic_map_size",
            Knob::Spp => "spp",
        }
    }

    /// The knob called `name`, if there is one.
    pub fn parse(name: &str) -> Option<Knob> {
        Knob::ALL.into_iter().find(|knob| knob.name() == name)
    }

    /// Every knob's name, comma-separated, for messages.
    pub fn names() -> String {
        Knob::ALL.map(Knob::name).join(", ")
    }

    /// The values the renderer takes for the knob, inclusive.
    pub fn range(self) -> (u32, u32) {
        match self {
            Knob::Vpls => (1, 65_536),
            Knob::IsmSize => (0, 512),
            Knob::IsmPoints => (1, 65_536),
            Knob::RsmSize => (4, 1024),
            Knob::ShadowMapSize => (16, 4096),
            Knob::Bounces => (1, crate::gpu::MAX_BOUNCES),
            Knob::BounceCandidates => (1, 65_536),
            Knob::CausticMapSize => (0, 4096),
            Knob::Spp => (1, 65_536),
        }
    }

    /// Whether the knob changes anything only where the `gi` factor is on (DIR's indirect
    /// light); `shadow_map_size` also needs shadows, `caustic_map_size` a mirror or glass
    /// object, `spp` nothing (the path tracer renders the whole scene).
    pub fn needs_gi(self) -> bool {
        matches!(
            self,
            Knob::Vpls | Knob::IsmSize | Knob::IsmPoints | Knob::RsmSize | Knob::Bounces | Knob::BounceCandidates
        )
    }
}

impl std::fmt::Display for Knob {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        formatter.write_str(self.name())
    }
}

/// A knob at one value: one level of a threshold study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct KnobSetting {
    pub knob: Knob,
    pub value: u32,
}

impl KnobSetting {
    /// Sets the knob in the GPU's parameters (the `vpls` and `spp` knobs live in the stimulus
    /// settings, not here). The caustic map size changes only where caustics are on.
    pub fn apply(self, params: &mut crate::gpu::DirParams) {
        match self.knob {
            Knob::IsmSize => params.ism_size = self.value,
            Knob::IsmPoints => params.ism_points = self.value,
            Knob::RsmSize => params.rsm_size = self.value,
            Knob::ShadowMapSize => params.shadow_map_size = self.value,
            Knob::Bounces => params.bounces = self.value,
            Knob::BounceCandidates => params.bounce_candidates = self.value,
            Knob::CausticMapSize => {
                if params.specular.caustic_map_size > 0 {
                    params.specular.caustic_map_size = self.value;
                }
            }
            Knob::Vpls | Knob::Spp => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_knob_parses_by_its_name_and_has_a_range() {
        for knob in Knob::ALL {
            assert_eq!(Knob::parse(knob.name()), Some(knob));
            let (low, high) = knob.range();
            assert!(low <= high, "{knob}");
        }
        assert_eq!(Knob::parse("vpl"), None);
    }

    #[test]
    fn each_gpu_knob_changes_its_own_setting_only() {
        let base = crate::gpu::DirParams::default();
        for knob in [
            Knob::IsmSize,
            Knob::IsmPoints,
            Knob::RsmSize,
            Knob::ShadowMapSize,
            Knob::Bounces,
            Knob::BounceCandidates,
            Knob::CausticMapSize,
        ] {
            let mut params = base.clone();
            KnobSetting { knob, value: 7 }.apply(&mut params);
            let changed = [
                params.ism_size != base.ism_size,
                params.ism_points != base.ism_points,
                params.rsm_size != base.rsm_size,
                params.shadow_map_size != base.shadow_map_size,
                params.bounces != base.bounces,
                params.bounce_candidates != base.bounce_candidates,
                params.specular.caustic_map_size != base.specular.caustic_map_size,
            ];
            assert_eq!(changed.iter().filter(|c| **c).count(), 1, "{knob}");
            assert_eq!(params.vpls, base.vpls);
        }
    }

    #[test]
    fn a_knob_changes_the_fingerprint_and_no_knob_keeps_it() {
        use crate::stimulus::{Factors, StimulusSettings};
        let settings = StimulusSettings { width: 64, height: 48, ..StimulusSettings::default() };
        let scene = settings.sized(crate::scene::load("dir-lamp-box").unwrap());
        let gi = Factors::from_levels([("gi", 1.0)]).unwrap();
        let base = settings.fingerprint(&scene, &gi);
        assert_eq!(settings.with_knob(None).fingerprint(&scene, &gi), base);
        assert!(!base.contains("knob"), "{base}");
        // vpls is the settings' own budget: the same stimulus as a study with that budget
        let vpls = settings.with_knob(Some(KnobSetting { knob: Knob::Vpls, value: 64 }));
        assert_eq!(vpls, StimulusSettings { vpls: 64, ..settings.clone() });
        let ism = |value| settings.with_knob(Some(KnobSetting { knob: Knob::IsmSize, value })).fingerprint(&scene, &gi);
        assert_ne!(ism(64), base);
        assert_ne!(ism(64), ism(32));
        assert!(ism(64).contains("knob ism_size 64"), "{}", ism(64));
        let spp = settings.with_knob(Some(KnobSetting { knob: Knob::Spp, value: 4 }));
        assert_ne!(spp.fingerprint(&scene, &gi), base);
        assert_eq!(spp.params(&scene, &gi).ism_size, settings.params(&scene, &gi).ism_size);
    }
}
