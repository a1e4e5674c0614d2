//! The scene representation a coherent frame queries, built from a capture: the light probe
//! for what the capture missed, the distance impostors (EM, DIT) or the scene voxel volume
//! (VCT), and each virtual object's solid volume for its self-shadows — on the GPU where a
//! renderer is given ([`crate::gpu::representation`]), else on the CPU — with what each pass
//! took.

use super::impostor::SPLAT_RADIUS;
use super::*;

/// The light probe's width in texels (its height is half) and paths per texel.
pub const PROBE_WIDTH: u32 = 128;
pub const PROBE_PATHS: u32 = 8;

/// The light probe at `centre`: the real scene path traced in every direction from there, an
/// equirectangular map `width` × `width`/2 with `spp` paths per texel.
pub fn light_probe(real: &World, centre: Vec3, width: u32, spp: u32, seed: u64) -> Environment {
    let (w, h) = (width.max(4), (width / 2).max(2));
    let mut map = Image::new(w, h);
    let params = TraceParams { seed, ..TraceParams::default() };
    let spp = spp.max(1);
    map.pixels = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let (i, j) = (k % w, k / w);
            let mut rng = Rng::for_stream(seed, 0x9_0be, k as u64);
            let mut sum = Vec3::ZERO;
            for _ in 0..spp {
                // jittered within the texel
                let u = (i as f32 + rng.next_f32()) / w as f32;
                let v = (j as f32 + rng.next_f32()) / h as f32;
                let (l, _) = real.radiance(Ray { origin: centre, dir: equirect_dir(u, v) }, &mut rng, &params);
                if l.is_finite() {
                    sum += l;
                }
            }
            sum / spp as f32
        })
        .collect();
    Environment::new(map, 0.0)
}

/// The bounds of a scene's virtual objects (None without one).
pub fn virtual_bounds(scene: &Scene) -> Option<Aabb> {
    scene
        .objects
        .iter()
        .filter(|o| o.role == Role::Virtual)
        .flat_map(|o| o.prims.iter().map(|p| p.bounds()))
        .reduce(|a, b| a.union(&b))
}

/// The bounds of each virtual object of a scene, in the scene's order.
pub fn virtual_object_bounds(scene: &Scene) -> Vec<Aabb> {
    scene
        .objects
        .iter()
        .filter(|o| o.role == Role::Virtual)
        .filter_map(|o| o.prims.iter().map(|p| p.bounds()).reduce(|a, b| a.union(&b)))
        .collect()
}

/// Builds what `method` queries from the captured `samples` (footprint: the hash grid's
/// cell), with the light probe at the virtual object for what the capture missed; returns the
/// representation and the build passes with their times. With `gpu`, the distance impostors
/// and the scene voxel volume are built by its compute passes ([`crate::gpu::representation`],
/// texel for texel the CPU's builds, tested) and read back; a build the adapter cannot hold
/// falls back to the CPU, and the pass's name says why. The light probe is path traced on the
/// CPU.
pub fn build_representation(
    scene: &Scene,
    real: &World,
    samples: &[EnvironmentSample],
    footprint: f32,
    params: &CoherentParams,
    gpu: Option<&crate::gpu::DirRenderer>,
) -> (Representation, Vec<PassTime>) {
    let centre = virtual_bounds(scene).map_or(scene.camera.position, |b| b.centroid());
    let start = Instant::now();
    let probe = light_probe(real, centre, PROBE_WIDTH, PROBE_PATHS, params.seed);
    let size = format!("{PROBE_WIDTH}×{}, {PROBE_PATHS} paths per texel", PROBE_WIDTH / 2);
    let mut passes = vec![PassTime::new(format!("light probe ({size})"), ms_since(start))];
    let prebuilt = Prebuilt { sky: Arc::new(probe), voxels: None, solids: None };
    let (rep, built) = build_queries(scene, samples, footprint, params, gpu, prebuilt);
    passes.extend(built);
    (rep, passes)
}

/// What [`build_queries`] takes ready-made: `sky`, the light probe for what the capture missed;
/// `voxels`, a scene voxel volume built before from the same samples at the settings' size;
/// `solids`, the virtual objects' solid volumes already placed.
#[derive(Clone, Debug)]
pub struct Prebuilt {
    pub sky: Arc<Environment>,
    pub voxels: Option<Arc<VoxelVolume>>,
    pub solids: Option<Vec<SolidVolume>>,
}

/// What `params.method` queries, built from the captured `samples` around the virtual objects
/// where they are now, with `sky` (the light probe) for what the capture missed: the distance
/// impostors (EM, DIT; one per virtual object, centred in it) or the scene voxel volume (VCT),
/// which does not depend on the objects — `voxels`, one built before from the same samples at
/// the settings' size, is reused — and, where self-shadows are tested, each virtual object's
/// solid volume ([`solid`]), unless `solids` brings them already placed. With
/// `gpu`, built as [`build_representation`] says.
pub fn build_queries(
    scene: &Scene,
    samples: &[EnvironmentSample],
    footprint: f32,
    params: &CoherentParams,
    gpu: Option<&crate::gpu::DirRenderer>,
    prebuilt: Prebuilt,
) -> (Representation, Vec<PassTime>) {
    let Prebuilt { sky, voxels, solids } = prebuilt;
    let mut passes = Vec::new();
    let mut rep = Representation { sky: Some(sky), ..Representation::default() };
    if params.method == Method::Off {
        return (rep, passes);
    }
    // where a build ran, as the pass names it: the GPU's times and memory, or why the CPU;
    // the passes compile (on first use) before the clock starts
    let builder = gpu.map(|r| (r, r.representation_builder()));
    if params.settings.self_shadow {
        match solids {
            Some(solids) => rep.solids = solids,
            None => {
                let (solids, exact, pass) = build_solids(scene, params.settings.object_voxels, builder);
                (rep.solids, rep.exact_self_shadows) = (solids, exact);
                passes.push(pass);
            }
        }
    }
    let mut on_gpu = GpuBuilds::default();
    if params.method != Method::Vct {
        let start = Instant::now();
        let n = params.settings.impostor_size;
        let mut centres: Vec<Vec3> = virtual_object_bounds(scene).iter().map(|b| b.centroid()).collect();
        if centres.is_empty() {
            centres.push(scene.camera.position);
        }
        rep.impostors = match builder {
            Some((r, builder)) => centres
                .iter()
                .map(|&c| {
                    on_gpu
                        .add(
                            builder
                                .impostor(&r.ctx, samples, c, n, SPLAT_RADIUS * footprint)
                                .map(|built| built.map(Into::into)),
                        )
                        .unwrap_or_else(|| DistanceImpostor::build(samples, c, n, footprint))
                })
                .collect(),
            None => centres.par_iter().map(|&c| DistanceImpostor::build(samples, c, n, footprint)).collect(),
        };
        let count = rep.impostors.len();
        let what = if count == 1 {
            format!("distance impostor (6×{n}²)")
        } else {
            format!("{count} distance impostors (6×{n}² each, one per virtual object)")
        };
        passes.push(PassTime::new(on_gpu.name(what, gpu), ms_since(start)));
    } else if let Some(voxels) = voxels.filter(|v| v.res == params.settings.scene_voxels) {
        rep.voxels = Some(voxels);
    } else {
        let start = Instant::now();
        let n = params.settings.scene_voxels;
        rep.voxels = Some(Arc::new(match builder {
            Some((r, builder)) => on_gpu
                .add(
                    builder
                        .voxels(&r.ctx, samples, VoxelVolume::frame(samples, n, footprint), SPLAT_RADIUS * footprint)
                        .map(|built| built.map(Into::into)),
                )
                .unwrap_or_else(|| VoxelVolume::build(samples, n, footprint)),
            None => VoxelVolume::build(samples, n, footprint),
        }));
        let what = format!("scene voxel volume ({n}³ with mipmaps)");
        passes.push(PassTime::new(on_gpu.name(what, gpu), ms_since(start)));
    }
    (rep, passes)
}

/// Each virtual object's solid volume, `n` voxels along its longest axis, with the pass that
/// built them: on `gpu` where one is given ([`crate::gpu::representation`]: the sweeps and τ's
/// mip levels) unless a virtual material has an image texture or a voxel column meets too many
/// primitives, else on the CPU, the pass saying why; none, and `true` (intersect the objects
/// exactly), when some virtual object is not closed, as the pass then says.
fn build_solids(
    scene: &Scene,
    n: u32,
    gpu: Option<(&crate::gpu::DirRenderer, &crate::gpu::representation::RepresentationBuilder)>,
) -> (Vec<SolidVolume>, bool, PassTime) {
    let start = Instant::now();
    let open: Vec<&str> = scene
        .objects
        .iter()
        .filter(|o| o.role == Role::Virtual && !solid::is_closed(&o.prims))
        .map(|o| o.name.as_str())
        .collect();
    if !open.is_empty() {
        let what = format!(
            "object solid volumes: none, {} not closed (parity voxelisation needs closed objects), so the objects are intersected exactly",
            open.join(", ")
        );
        return (Vec::new(), true, PassTime::new(what, ms_since(start)));
    }
    let bounds = virtual_object_bounds(scene);
    let on_cpu = |b: &[Aabb]| {
        let object = World::new(scene, Subset::VirtualOnly);
        b.par_iter().map(|&b| SolidVolume::build(&object, b, n)).collect::<Vec<_>>()
    };
    let mut on_gpu = GpuBuilds::default();
    let solids: Vec<SolidVolume> = match gpu.map(|(r, builder)| (r, builder, solid_primitives(scene))) {
        Some((r, builder, Ok(prims))) => bounds
            .iter()
            .map(|&b| {
                let (voxel, dims) = SolidVolume::frame(&b, n);
                on_gpu
                    .add(builder.solid_sweeps(&r.ctx, &prims, b, voxel, dims))
                    .map(|sweeps| SolidVolume::from_sweeps(b.min, voxel, dims, sweeps))
                    .unwrap_or_else(|| on_cpu(&[b]).remove(0))
            })
            .collect(),
        Some((_, _, Err(reason))) => {
            on_gpu.fallback = Some(reason);
            on_cpu(&bounds)
        }
        None => on_cpu(&bounds),
    };
    let dims: Vec<String> = solids
        .iter()
        .map(|v| {
            let d = v.dims();
            format!("{}×{}×{}", d.x, d.y, d.z)
        })
        .collect();
    let what = format!("object solid volumes ({}, with mipmaps)", dims.join(", "));
    (solids, false, PassTime::new(on_gpu.name(what, gpu.map(|(r, _)| r)), ms_since(start)))
}

/// The virtual objects' primitives as the GPU's solid sweeps read them, with their materials'
/// albedo and pattern, or why they cannot: an image texture (the sweeps evaluate the procedural
/// patterns only).
pub(super) fn solid_primitives(
    scene: &Scene,
) -> std::result::Result<Vec<crate::gpu::representation::SolidPrimitive>, String> {
    let mut prims = Vec::new();
    for o in scene.objects.iter().filter(|o| o.role == Role::Virtual) {
        let material = &scene.materials[o.material];
        if let Some(crate::material::Texture::Image(_)) = material.texture {
            return Err(format!(
                "{}'s material `{}` has an image texture, which the GPU's sweeps do not evaluate",
                o.name, material.name
            ));
        }
        prims.extend(o.prims.iter().map(|prim| crate::gpu::representation::SolidPrimitive {
            prim: prim.clone(),
            albedo: material.albedo,
            pattern: material.texture.clone(),
            delta: material.delta.is_some(),
        }));
    }
    Ok(prims)
}

/// What the GPU builds of one pass took, and why any fell back to the CPU.
#[derive(Default)]
struct GpuBuilds {
    gpu_ms: f64,
    readback_ms: f64,
    bytes: u64,
    fallback: Option<String>,
}

impl GpuBuilds {
    /// The built value, counted, or None (and the reason kept) where the GPU could not build it.
    fn add<T>(
        &mut self,
        built: std::result::Result<crate::gpu::representation::Built<T>, crate::gpu::representation::BuildRefused>,
    ) -> Option<T> {
        match built {
            Ok(built) => {
                self.gpu_ms += built.gpu_ms;
                self.readback_ms += built.readback_ms;
                self.bytes += built.gpu_bytes;
                Some(built.value)
            }
            Err(reason) => {
                self.fallback = Some(reason.to_string());
                None
            }
        }
    }

    /// The pass's name: `what`, and where it was built.
    fn name(&self, what: String, gpu: Option<&crate::gpu::DirRenderer>) -> String {
        match (gpu, &self.fallback) {
            (None, _) => format!("{what} on the CPU"),
            (Some(_), Some(reason)) => format!("{what} on the CPU: {reason}"),
            (Some(r), None) => format!(
                "{what} on {}: GPU {:.1} ms, readback {:.1} ms, {:.1} MB",
                r.ctx.adapter_name(),
                self.gpu_ms,
                self.readback_ms,
                self.bytes as f64 / 1e6
            ),
        }
    }
}
