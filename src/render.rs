//! `mrstudy render`: its flags into `mrstudy_renderer::command::RenderRequest` (with a study's
//! conditions for `--contact-sheet --study`), run by `command::render` on the console.

use std::path::PathBuf;

use crate::Say;
use anyhow::Result;
use mrstudy_renderer::ca::ParamSource;
use mrstudy_renderer::cm::{CmMethod, Composition};
use mrstudy_renderer::coherent::{Method, Quality};
use mrstudy_renderer::command::{RenderRequest, render};
use mrstudy_renderer::gpu::GiLevel;
use mrstudy_renderer::gpu::ism::IsmSplatting;
use mrstudy_renderer::scene;
use mrstudy_renderer::sensor::SensorParams;
use mrstudy_renderer::stimulus::{Factors, RenderKnobs};

flags! {
    RenderArgs {
        #[command(flatten)] request: RenderFlags,
        /// The conditions of the contact sheet: those of this study file (default: the web survey's eight, LQ … HQ).
        #[arg(long, value_name = "FILE", requires = "contact_sheet")] study: Option<PathBuf>,
    }
}

flags! {
    RenderFlags => RenderRequest { conditions: None } {
        /// List the built-in scene names, one per line.
        #[arg(long)] list: bool,
        /// A built-in scene name or a scene file (TOML).
        #[arg(long)] scene: Option<String>,
        /// Render the ground-truth composite (real and virtual objects) with the reference path tracer.
        #[arg(long, conflicts_with_all = ["photo", "condition", "factors", "cm"])] reference: bool,
        /// Render the photograph (real objects only) with the reference path tracer.
        #[arg(long, conflicts_with_all = ["condition", "factors", "cm"])] photo: bool,
        /// A condition by name, on the GPU: `gi` (shadows and indirect light), `shadows`, or `none`.
        #[arg(long, conflicts_with = "factors", value_parser = crate::choice(GiLevel::parse, "gi, shadows, none (for colour mapping add --cm, for camera artifacts use --factors)"))] condition: Option<GiLevel>,
        /// Factors to switch on, on the GPU: `gi` (indirect light and shadows), `cm` (the statistics-based colour mapping), `ca` (camera artifacts); caustics of mirrors and glass come with `gi` and `shadows` (`--caustic-map-size 0` turns them off).
        #[arg(long, value_parser = Factors::parse_list)] factors: Option<Factors>,
        #[command(flatten)] knobs: KnobsFlags,
        /// Render by one of Rohmer et al.'s methods from a simulated capture of the real scene (CPU): `em`, `dit`, `vct`, or `off` (no coherent rendering); prints its errors against the ground truth.
        #[arg(long, conflicts_with_all = ["reference", "photo", "condition", "factors", "cm"], value_parser = crate::choice(Method::parse, "em, dit, vct, off"))] gi_method: Option<Method>,
        /// The paper's quality setting of `--gi-method`: low, med or high.
        #[arg(long, default_value = "med", value_parser = crate::choice(Quality::parse, "low, med, high"))] quality: Quality,
        /// Samples per pixel of the reference path tracer.
        #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..))] spp: u32,
        /// Image size WxH (intrinsics scale with it); default: the scene's.
        #[arg(long, value_parser = scene::parse_size)] size: Option<(u32, u32)>,
        /// Random seed of the path tracer.
        #[arg(long, default_value_t = 1)] seed: u64,
        /// Replace the scene's simulated camera by a preset: webcam, phone or clean.
        #[arg(long, value_parser = crate::choice(SensorParams::preset, "webcam, phone, clean"))] camera: Option<SensorParams>,
        /// Output image: `.png` (camera output) or `.exr` (linear HDR radiance).
        #[arg(long)] out: Option<PathBuf>,
        /// Also write every buffer into this directory: photo.png, ground_truth.png, real.exr, full.exr, virtual_mask.png, affected_mask.png, report.json.
        #[arg(long)] buffers: Option<PathBuf>,
        /// Print the scene as a scene file (TOML) and exit.
        #[arg(long)] print_toml: bool,
        /// Write a contact sheet (PNG): the ground truth, the photograph and the stimulus of each condition side by side, labelled, rendered as a study renders them (default size 200x150).
        #[arg(long, value_name = "FILE.png", conflicts_with_all = ["reference", "photo", "condition", "factors", "gi_method", "out"])] contact_sheet: Option<PathBuf>,
    }
}

flags! {
    /// [`RenderKnobs`]' flags; their defaults are its `Default` (a test checks).
    KnobsFlags => RenderKnobs {} {
        /// GPU: the VPL budget of the `gi` condition.
        #[arg(long, default_value_t = RenderKnobs::default().vpls)] vpls: u32,
        /// GPU: resolution of each VPL's imperfect shadow map (0: VPLs unshadowed).
        #[arg(long, default_value_t = RenderKnobs::default().ism_size)] ism_size: u32,
        /// GPU: points per cloud (real, virtual) splatted into each VPL's imperfect shadow map.
        #[arg(long, default_value_t = RenderKnobs::default().ism_points)] ism_points: u32,
        /// GPU: how the imperfect shadow maps' splats are drawn: `compute` (a compute pass, atomics) or `raster` (the rasteriser, depth test).
        #[arg(long, default_value = "compute", value_parser = crate::choice(IsmSplatting::parse, "compute, raster"))] ism_splatting: IsmSplatting,
        /// GPU: bounces of indirect light in the `gi` condition (1: the single bounce of the RSM VPLs; more add the multiple-bounce light source of thesis 5.2.7, at most 8).
        #[arg(long, default_value_t = RenderKnobs::default().bounces, value_parser = clap::value_parser!(u32).range(1..=8))] bounces: u32,
        /// GPU: candidate points each multiple-bounce slot searches.
        #[arg(long, default_value_t = RenderKnobs::default().bounce_candidates)] bounce_candidates: u32,
        /// GPU: the composition: additive (default) or scaled (Debevec: α = L'_cam / τ(L_r)).
        #[arg(long, default_value = "additive", value_parser = crate::choice(Composition::parse, "additive, scaled"))] composition: Composition,
        /// GPU: the colour mapping of the GI buffers: off (Reinhard), statistics, samples or rohmer (overrides what the `cm` factor implies).
        #[arg(long, value_parser = crate::choice(CmMethod::parse, "off, statistics, samples, rohmer"))] cm: Option<CmMethod>,
        /// Where the `ca` factor takes its parameters: `scene` (the scene's simulated camera) or `estimate` (noise, blur and JPEG quality measured on the photograph).
        #[arg(long = "ca-params", default_value = "scene", value_parser = crate::choice(ParamSource::parse, "scene, estimate"))] ca_source: ParamSource,
        /// GPU: resolution of each caustic map of a mirror or glass object (0: no caustics).
        #[arg(long, default_value_t = RenderKnobs::default().caustic_map_size)] caustic_map_size: u32,
    }
}

pub fn run(args: RenderArgs, say: Say) -> Result<()> {
    // the study is read only where the sheet is drawn (after the scene is named)
    let sheet = args.request.contact_sheet.is_some() && args.request.scene.is_some() && !args.request.list;
    let conditions =
        args.study.as_deref().filter(|_| sheet).map(mrstudy_server::study::sheet_conditions).transpose()?;
    Ok(render(&RenderRequest { conditions, ..args.request.into() }, say)?)
}
