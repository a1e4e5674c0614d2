//! Tests of VPL creation: flux and flags (eqs. 5.9–5.10), resampling and the budget split, and
//! the GPU sampler against the CPU's reference.

use super::*;

fn spot(real: bool) -> SpotLight {
    SpotLight {
        name: "s".into(),
        position: Vec3::new(0.0, 1.0, 0.0),
        direction: Vec3::NEG_Y,
        cos_inner: 0.5,
        cos_outer: 0.4,
        intensity: Vec3::ONE,
        real,
    }
}

fn texel(y: f32, flag: f32, albedo: f32) -> RsmTexel {
    ([0.0, y, 0.0, flag], [0.0, 1.0, 0.0, 1.0], [albedo, albedo, albedo, 0.0], 1.0 - y)
}

const EMPTY: RsmTexel = ([0.0; 4], [0.0; 4], [0.0; 4], 1e30);

#[test]
fn flux_is_conserved_and_flags_follow_section_5_2_3() {
    // one texel: a real floor with a virtual box in front, under a real light
    let rsm =
        RsmTexels { size: 1, tan_half_fov: 0.1, real: vec![texel(0.0, 1.0, 0.5)], virt: vec![texel(0.5, 2.0, 0.8)] };
    let light = spot(true);
    let vpls = create(&[(RsmLight::Spot(&light), rsm)], 64);
    assert_eq!(vpls.len(), 64);
    let (virt, real): (Vec<&GpuVpl>, Vec<&GpuVpl>) = vpls.iter().partition(|v| v.position[3] == 0.0);
    assert!(virt.iter().all(|v| v.normal[3] == 0.0), "a VPL on a virtual surface lights L_rv");
    assert!(real.iter().all(|v| v.normal[3] == 1.0), "a real VPL behind a virtual one lights L_r only");
    // expected flux of each: albedo · I · dω; their sums are preserved by the sampling
    let d_omega = 0.2f32 * 0.2;
    let sum = |vs: &[&GpuVpl]| vs.iter().map(|v| v.flux[0]).sum::<f32>();
    // stratified sampling rounds each candidate's share to whole VPLs: within 1/N
    assert!((sum(&virt) / (0.8 * d_omega) - 1.0).abs() < 2.0 / 64.0, "{}", sum(&virt));
    assert!((sum(&real) / (0.5 * d_omega) - 1.0).abs() < 2.0 / 64.0, "{}", sum(&real));
}

#[test]
fn an_environment_direction_reflects_albedo_times_irradiance_times_texel_area() {
    // two texels: a real floor, and a virtual box in front of the real floor
    let rsm = RsmTexels {
        size: 2,
        tan_half_fov: 0.0,
        real: vec![texel(0.0, 1.0, 0.5), texel(0.0, 1.0, 0.5), EMPTY, EMPTY],
        virt: vec![EMPTY, texel(0.5, 2.0, 0.8), EMPTY, EMPTY],
    };
    let light = RsmLight::Directional { irradiance: Vec3::splat(2.0), texel_area: 0.01 };
    let vpls = create(&[(light, rsm)], 300);
    assert_eq!(vpls.len(), 300);
    let sum = |f: &dyn Fn(&GpuVpl) -> bool| vpls.iter().filter(|v| f(v)).map(|v| v.flux[0] as f64).sum::<f64>();
    // the open floor texel: a real path (r = 1, ir = 0), flux 0.5 · 2 · 0.01
    let open = sum(&|v| v.position[3] == 1.0 && v.normal[3] == 0.0);
    assert!((open / 0.01 - 1.0).abs() < 0.02, "{open}");
    // the virtual box (r = 0) and the real floor behind it, for the real-only solution (ir = 1)
    let virt = sum(&|v| v.position[3] == 0.0);
    let behind = sum(&|v| v.normal[3] == 1.0);
    assert!((virt / 0.016 - 1.0).abs() < 0.02 && (behind / 0.01 - 1.0).abs() < 0.02, "{virt} {behind}");
}

#[test]
fn resampling_keeps_the_flux_and_the_budget_split_follows_it() {
    let vpl = |f: f32| GpuVpl { position: [0.0; 4], normal: [0.0, 1.0, 0.0, 0.0], flux: [f, f, f, 0.0] };
    let set: Vec<GpuVpl> = (1..=40).map(|k| vpl(k as f32)).collect();
    let drawn = resample(&set, 10);
    assert_eq!(drawn.len(), 10);
    assert!((luminance_flux(&drawn) / luminance_flux(&set) - 1.0).abs() < 1e-5);
    assert!(resample(&[vpl(0.0), vpl(f32::NAN)], 4).is_empty());
    assert_eq!(split_budget(256, &[3.0, 1.0]), vec![192, 64]);
    assert_eq!(split_budget(10, &[1.0, 1.0, 1.0]).iter().sum::<u32>(), 10);
    assert_eq!(split_budget(4, &[1000.0, 1.0]), vec![3, 1], "every source with flux gets a VPL");
    assert_eq!(split_budget(8, &[1.0, 0.0, f64::NAN]), vec![8, 0, 0]);
    assert_eq!(split_budget(8, &[0.0]), vec![0]);
}

#[test]
fn virtual_light_gives_no_vpl_behind_virtual_surfaces_and_no_real_path_flag() {
    let rsm = RsmTexels {
        size: 2,
        tan_half_fov: 0.1,
        real: vec![texel(0.0, 1.0, 0.5), texel(0.0, 1.0, 0.5), EMPTY, EMPTY],
        virt: vec![texel(0.5, 2.0, 0.8), EMPTY, EMPTY, EMPTY],
    };
    let light = spot(false);
    let vpls = create(&[(RsmLight::Spot(&light), rsm)], 16);
    assert!(vpls.iter().all(|v| v.position[3] == 0.0 && v.normal[3] == 0.0));
}

/// Random RSMs (a real spot's two maps, an environment direction without a virtual map), as
/// textures for the GPU sampler and as texels for the CPU's reference.
fn random_maps(
    ctx: &crate::gpu::context::GpuContext,
    size: u32,
    seed: u64,
) -> Vec<(RsmTexels, [std::sync::Arc<wgpu::Texture>; 4])> {
    let mut state = seed;
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    let mut maps = Vec::new();
    for virtual_map in [false, true] {
        let texels: Vec<RsmTexel> = (0..size * size)
            .map(|k| {
                // a quarter empty; a virtual map's surfaces nearer or farther than the real one's
                if next() < 0.25 {
                    return EMPTY;
                }
                let flag = if virtual_map { 2.0 + 4.0 * (k % 3) as f32 } else { 1.0 + 4.0 * (k % 2) as f32 };
                let (x, z) = (next() * 4.0 - 2.0, next() * 4.0 - 2.0);
                let albedo = if k == 7 { f32::NAN } else { next() };
                ([x, next() * 0.3, z, flag], [0.0, 1.0, 0.0, 0.0], [albedo, next(), next(), 0.0], 1.0 + next())
            })
            .collect();
        let quads = |f: &dyn Fn(&RsmTexel) -> [f32; 4]| -> Vec<f32> { texels.iter().flat_map(f).collect() };
        let upload = |data: Vec<f32>, format: wgpu::TextureFormat, texel_bytes: u32| {
            let texture = crate::gpu::raster::texture_2d(ctx, size, size, format, "test rsm");
            ctx.write_texture(
                texture.as_image_copy(),
                bytemuck::cast_slice(&data),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(size * texel_bytes),
                    rows_per_image: None,
                },
                wgpu::Extent3d { width: size, height: size, depth_or_array_layers: 1 },
            );
            texture
        };
        let surface = crate::gpu::raster::SURFACE_FORMAT;
        let textures = [
            upload(quads(&|t| t.0), surface, 16),
            upload(quads(&|t| t.1), surface, 16),
            upload(quads(&|t| t.2), surface, 16),
            upload(texels.iter().map(|t| t.3).collect(), crate::gpu::raster::DISTANCE_FORMAT, 4),
        ];
        maps.push((RsmTexels { size, tan_half_fov: 0.9, real: texels.clone(), virt: texels }, textures));
    }
    maps
}

/// The GPU sampler against the CPU's reference on random RSMs (a spot with both maps, an
/// environment direction with its real map only, a NaN albedo) and extra candidates (as the
/// renderer's CPU path passes the caustic ones; `cs_caustic_candidates` is compared in the
/// gi frames of `a_gi_frames_vpls_are_the_same_made_on_the_gpu_or_the_cpu`): every drawn VPL
/// of 1, 7, 256 and 1000 is the same candidate with the same flux to f32 rounding, except at
/// most two neighbours over all 1264 (none on lavapipe: the f32 CDF's rounding).
#[test]
fn the_gpu_sampler_draws_the_cpu_references_vpls() {
    let Some(renderer) = crate::test_support::renderer_or_skip() else { return };
    let ctx = &renderer.ctx;
    let size = 48;
    let maps = random_maps(ctx, size, 17);
    let (real, virt) = (&maps[0], &maps[1]);
    let light = SpotLight { cos_inner: 0.8, cos_outer: 0.6, intensity: Vec3::new(3.0, 2.0, 1.0), ..spot(true) };
    let environment = RsmLight::Directional { irradiance: Vec3::new(0.5, 0.7, 1.1), texel_area: 0.003 };
    let extra: Vec<GpuVpl> = (0..5)
        .map(|k| GpuVpl {
            position: [k as f32, 0.0, 0.0, 0.0],
            normal: [0.0, 1.0, 0.0, 0.0],
            flux: [0.002 * k as f32, 0.001, 0.0, 1.0],
        })
        .collect();
    // the spot with both maps; the environment direction with only its real map
    let cpu_lights = vec![
        (
            RsmLight::Spot(&light),
            RsmTexels { size, tan_half_fov: 0.9, real: real.0.real.clone(), virt: virt.0.real.clone() },
        ),
        (
            environment,
            RsmTexels { size, tan_half_fov: 0.0, real: real.0.real.clone(), virt: vec![EMPTY; (size * size) as usize] },
        ),
    ];
    let gpu_maps = vec![
        RsmMaps {
            light: RsmLight::Spot(&light),
            tan_half_fov: 0.9,
            size,
            real: real.1.each_ref(),
            virt: Some(virt.1.each_ref()),
        },
        RsmMaps { light: environment, tan_half_fov: 0.0, size, real: real.1.each_ref(), virt: None },
    ];
    let sampler = VplSampler::new(ctx);
    let candidates = sampler.candidates(ctx, &extra, &[], &gpu_maps);
    assert_eq!(candidates.slots(), 5 + 2 * 2 * size * size);
    let reference = Candidates::new(&cpu_lights, &extra);
    let mut kinds = [0usize; 4];
    let mut neighbours = Vec::new();
    for count in [1, 7, 256, 1000] {
        let (gpu, cpu) = (sampler.draw(ctx, &candidates, count), reference.draw(count));
        assert_eq!(gpu.len(), cpu.len(), "{count} VPLs");
        for (k, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
            // the same candidate (position, normal, flags), the same flux to f32 rounding
            if (g.position, g.normal, g.flux[3]) != (c.position, c.normal, c.flux[3]) {
                neighbours.push((count, k, *g, *c));
                continue;
            }
            for channel in 0..3 {
                let (a, b) = (g.flux[channel], c.flux[channel]);
                assert!((a - b).abs() <= 2e-5 * b.abs().max(1e-12), "VPL {k} of {count}: flux {a} against {b}");
            }
            let kind = (c.flux[3] == 1.0) as usize * 3
                + (c.flux[3] != 1.0) as usize * (c.position[3] as usize + 2 * c.normal[3] as usize).min(2);
            kinds[kind.min(3)] += 1;
        }
    }
    assert!(neighbours.len() <= 2, "{} VPLs differ: {neighbours:?}", neighbours.len());
    // every kind of candidate was drawn: virtual (r = 0), real (r = 1), real behind virtual
    // (ir = 1) and caustic
    assert!(kinds.iter().all(|&n| n > 0), "{kinds:?}");
    // no candidate at all: nothing is drawn
    let dark = RsmLight::Directional { irradiance: Vec3::ZERO, texel_area: 0.003 };
    let dark = [RsmMaps { light: dark, tan_half_fov: 0.0, size, real: real.1.each_ref(), virt: None }];
    let none = sampler.candidates(ctx, &[], &[], &dark);
    assert!(sampler.draw(ctx, &none, 16).is_empty());
}
