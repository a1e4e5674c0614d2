//! Tests of the GPU renderer's parts: every shader parsed and validated by naga, the camera
//! matrix against the CPU camera (neither needs an adapter), and shadow maps drawn in one
//! submission against each drawn alone (on the adapter; lavapipe without a GPU).

use super::*;

/// Every WGSL file of the GPU renderer, found by walking `src/gpu/` (no list to forget),
/// parsed and validated by naga as the renderer compiles it: with the files the Rust beside it
/// puts in front (`common.wgsl`, `cdf.wgsl`). A shader no Rust file includes is an error.
#[test]
fn every_shader_parses_and_validates_with_naga() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/gpu");
    let rust: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|extension| extension == "rs"))
        .map(|path| std::fs::read_to_string(path).unwrap())
        .collect();
    let mut validated = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|extension| extension != "wgsl") {
            continue;
        }
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let include = format!("include_str!(\"{name}\")");
        let lines: Vec<&str> =
            rust.iter().flat_map(|text| text.lines()).filter(|line| line.contains(&include)).collect();
        assert!(!lines.is_empty(), "{name} is included by no Rust file in src/gpu");
        // the shader as the first Rust line including it builds it: every `include_str!` of that
        // line, in order (`common.wgsl` and `cdf.wgsl` in front of their users)
        let source: String = lines[0]
            .split("include_str!(\"")
            .skip(1)
            .map(|rest| rest.split('"').next().unwrap())
            .map(|file| std::fs::read_to_string(dir.join(file)).unwrap())
            .collect();
        let module =
            naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        let mut validator =
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all());
        validator.validate(&module).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        validated.push(name);
    }
    validated.sort();
    for expected in [
        "bounce.wgsl",
        "ca.wgsl",
        "cdf.wgsl",
        "cm.wgsl",
        "coherent.wgsl",
        "compose.wgsl",
        "indirect.wgsl",
        "ism.wgsl",
        "raster.wgsl",
        "representation.wgsl",
        "shade.wgsl",
        "specular.wgsl",
    ] {
        assert!(validated.iter().any(|name| name == expected), "{expected} not found: {validated:?}");
    }
}

#[test]
fn camera_matrix_projects_like_the_cpu_camera() {
    let camera = crate::camera::Camera::from_k(
        128,
        96,
        [100.0, 110.0, 60.0, 50.0],
        Vec3::new(0.2, 0.5, 1.0),
        Vec3::ZERO,
        Vec3::Y,
    );
    let m = camera_matrix(&camera, 0.01, 10.0);
    for p in [Vec3::new(0.1, 0.0, 0.0), Vec3::new(-0.2, 0.1, 0.3)] {
        let (u, v) = camera.project(p).unwrap();
        let clip = m * p.extend(1.0);
        let (x, y) = (clip.x / clip.w, clip.y / clip.w);
        assert!(((x * 0.5 + 0.5) * 128.0 - u).abs() < 1e-3, "{x} {u}");
        assert!(((0.5 - y * 0.5) * 96.0 - v).abs() < 1e-3, "{y} {v}");
        assert!((0.0..1.0).contains(&(clip.z / clip.w)));
    }
}

/// Shadow maps drawn together (one submission, their views in one uniform buffer, the depth
/// attachment reused from pass to pass) equal each drawn alone: a depth attachment that kept
/// the previous map's surfaces would leave the nearer of both in the second map.
#[test]
fn shadow_maps_drawn_together_equal_each_drawn_alone() {
    let Some(r) = crate::test_support::renderer_or_skip() else { return };
    let scene = crate::scene::load("dir-lamp-box").unwrap();
    let mesh = mesh::build(&scene);
    let buffers = SceneBuffers::new(&r.ctx, &mesh);
    let size = 64;
    let radius = mesh.bounds_radius;
    let view = |forward: Vec3| {
        let forward = forward.normalize();
        let (matrix, eye) = directional_view(forward, mesh.bounds_centre, radius, 2.0 * radius);
        ViewUniform::orthographic(matrix, eye, forward)
    };
    let (from_above, from_the_side) = (view(Vec3::new(0.1, -1.0, 0.2)), view(Vec3::new(-1.0, -0.3, 0.1)));
    let textures: Vec<wgpu::Texture> = (0..4)
        .map(|_| {
            r.ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("test shadow map"),
                size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: raster::DISTANCE_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        })
        .collect();
    let views: Vec<wgpu::TextureView> = textures.iter().map(|t| t.create_view(&Default::default())).collect();
    r.raster.shadow_map(&r.ctx, &buffers, &from_above, Subset::All, &views[0], size);
    r.raster.shadow_map(&r.ctx, &buffers, &from_the_side, Subset::All, &views[1], size);
    r.raster.shadow_maps(
        &r.ctx,
        &buffers,
        &[(from_the_side, Subset::All, &views[2]), (from_above, Subset::All, &views[3])],
        size,
    );
    let maps = r.ctx.read_textures(&textures.iter().map(|t| (t, 4)).collect::<Vec<_>>());
    assert_ne!(maps[0], maps[1], "the two views must differ for this test to tell anything");
    assert_eq!(maps[3], maps[0], "the map from above, drawn after the side view in one submission");
    assert_eq!(maps[2], maps[1], "the side view, drawn first in one submission");
}

/// GPU timestamps around every timed pass's submissions: a pass that draws or computes reports
/// its GPU time, no more than its wall-clock time; a pass on the CPU reports none; nothing is
/// written while passes are not timed, and a pass's timestamps are read once. (A software
/// adapter takes none unless asked, as here: lavapipe's timestamps miss some compute
/// dispatches, see `GpuContext::with_kind`.)
#[test]
fn timed_passes_report_the_gpu_time_of_their_own_submissions() {
    if crate::test_support::renderer_or_skip().is_none() {
        return;
    }
    // a renderer of its own: other tests' frames on the shared one would add their submissions
    let r = DirRenderer::new().unwrap();
    let frame_without = |r: &DirRenderer| {
        let scene = crate::scene::load("dir-lamp-box").unwrap().with_size(64, 48);
        let photo = crate::test_support::grey_photo(&scene);
        let params = DirParams { condition: GiLevel::Gi, vpls: 32, rsm_size: 32, ..DirParams::default() };
        (r.render(&scene, &photo, &params).unwrap(), scene, photo, params)
    };
    if r.ctx.kind == context::AdapterKind::Software {
        // off by default on a software adapter
        assert!(!r.ctx.has_gpu_timer());
        assert!(frame_without(&r).0.report.passes.iter().all(|p| p.gpu_ms.is_none()));
    }
    assert!(
        r.ctx.enable_gpu_timer() || r.ctx.kind != context::AdapterKind::Software,
        "lavapipe has timestamp queries; the test would tell nothing without them"
    );
    if !r.ctx.has_gpu_timer() {
        eprintln!("skipping the GPU-time checks: {} has no timestamp queries", r.ctx.adapter_name());
        return;
    }
    let (frame, scene, photo, params) = frame_without(&r);
    let pass = |prefix: &str| frame.report.passes.iter().find(|p| p.pass.starts_with(prefix)).unwrap();
    for drawn in ["g-buffer", "shading", "ISMs"] {
        let p = pass(drawn);
        let gpu = p.gpu_ms.unwrap_or_else(|| panic!("{}: no GPU time", p.pass));
        // the two clocks differ by their resolution at most
        assert!(gpu > 0.0 && gpu <= p.ms + 0.05, "{}: GPU {gpu} ms in {} ms", p.pass, p.ms);
    }
    for p in frame.report.passes.iter().filter(|p| p.pass.contains("(CPU)")) {
        assert_eq!(p.gpu_ms, None, "{} ran on the CPU", p.pass);
    }
    assert_eq!(r.ctx.take_gpu_ms(), None, "the frame's timestamps were all taken by its passes");
    r.ctx.set_pass_waits(false);
    let pipelined = r.render(&scene, &photo, &params);
    r.ctx.set_pass_waits(true);
    assert_eq!(pipelined.unwrap().composite.pixels, frame.composite.pixels);
    assert_eq!(r.ctx.take_gpu_ms(), None, "no timestamps while passes are not timed");
    r.ctx.submit(r.ctx.encoder());
    assert!(r.ctx.take_gpu_ms().is_some_and(|ms| ms >= 0.0));
    assert_eq!(r.ctx.take_gpu_ms(), None, "a submission's time is read once");
}

/// A gi frame's VPLs made on the GPU from the RSMs where they were rendered equal those the CPU
/// makes from the same RSMs read back (the reference, `vpl::Candidates`): with a spot and the
/// environment's directions, real and virtual maps, further bounces drawn from the first's
/// candidates twice, and a glass object's caustic VPLs among the candidates. The CDF is summed
/// in f32 on the GPU and in f64 on the CPU, so a stratum within rounding of a CDF step may take
/// the neighbouring candidate (on lavapipe none of dir-lamp-box's, one of the glass figure's 64);
/// the frames agree to a small fraction of the display range.
#[test]
fn a_gi_frames_vpls_are_the_same_made_on_the_gpu_or_the_cpu() {
    if crate::test_support::renderer_or_skip().is_none() {
        return;
    }
    // a renderer of its own: the CPU switch would reach other tests' frames on the shared one
    let r = DirRenderer::new().unwrap();
    for (name, (width, height)) in [("dir-lamp-box", (64, 48)), ("glass-figure", (48, 36))] {
        let scene = crate::scene::load(name).unwrap().with_size(width, height);
        let photo = crate::test_support::grey_photo(&scene);
        let mut params =
            DirParams { condition: GiLevel::Gi, vpls: 64, rsm_size: 32, bounces: 2, ..DirParams::default() };
        params.specular.caustic_map_size = 64;
        r.set_cpu_vpls(true);
        let cpu = r.render(&scene, &photo, &params).unwrap();
        r.set_cpu_vpls(false);
        let gpu = r.render(&scene, &photo, &params).unwrap();
        let on = |frame: &GpuRender, what: &str| frame.report.passes.iter().any(|p| p.pass.contains(what));
        assert!(on(&cpu, "RSMs read back") && !on(&gpu, "RSMs read back"), "{name}: each frame took its own path");
        let sampled = "VPL candidates and their CDF";
        assert!(on(&gpu, sampled) && !on(&cpu, sampled), "{name}: the GPU sampler's pass is reported");
        if name == "glass-figure" {
            let caustic = |frame: &GpuRender| frame.vpls.iter().filter(|v| v.flux[3] == 1.0).count();
            assert!(caustic(&cpu) > 0, "{name}: caustic VPLs are among those drawn");
            assert!(caustic(&gpu).abs_diff(caustic(&cpu)) <= 1, "{name}: {} and {}", caustic(&gpu), caustic(&cpu));
        }
        assert_eq!(gpu.vpls.len(), cpu.vpls.len(), "{name}");
        assert!(cpu.vpls.len() >= 64, "{name}: {} VPLs", cpu.vpls.len());
        let same =
            gpu.vpls.iter().zip(&cpu.vpls).filter(|(g, c)| g.position == c.position && g.normal == c.normal).count();
        // a neighbour (on lavapipe: one of glass-figure's 64, the floor's next texel) at most
        // once in 32 strata
        let n = cpu.vpls.len();
        assert!(n - same <= (n / 32).max(1), "{name}: {same} of {n} VPLs the same");
        let flux = |vpls: &[vpl::GpuVpl]| vpl::luminance_flux(vpls);
        assert!((flux(&gpu.vpls) / flux(&cpu.vpls) - 1.0).abs() < 1e-4, "{name}: total flux");
        let worst = gpu
            .composite
            .pixels
            .iter()
            .zip(&cpu.composite.pixels)
            .map(|(a, b)| (*a - *b).abs().max_element())
            .fold(0.0f32, f32::max);
        assert!(worst < 2e-3, "{name}: composites differ by up to {worst}");
    }
}

/// A live frame that is only shown (`render_display`, the lab's; it reads back the composite and
/// not L_rv and L_r) has `render_with_state`'s composite bit for bit, frame after frame
/// (temporal smoothing and the colour mapping's state carried the same way), with the ca
/// factor (which needs the virtual objects' mask from the radiance buffers) and without.
#[test]
fn a_frame_only_shown_is_the_live_frame_without_its_radiance_buffers() {
    let Some(r) = crate::test_support::renderer_or_skip() else { return };
    let scene = crate::scene::load("dir-lamp-box").unwrap().with_size(64, 48);
    let photo = Arc::new(crate::test_support::grey_photo(&scene));
    for ca in [false, true] {
        let params = DirParams {
            condition: GiLevel::Gi,
            vpls: 32,
            rsm_size: 32,
            camera_artifacts: ca.then(|| crate::ca::CaParams::from_sensor(&scene.sensor)),
            ..DirParams::default()
        };
        let (mut live, mut shown) = (LiveState::default(), LiveState::default());
        for frame in 0..2 {
            let full = r.render_with_state(&scene, &photo, &params, &mut live).unwrap();
            let display = r.render_display(&scene, &photo, &params, &mut shown).unwrap();
            // the shown frame's bytes (without ca packed on the GPU and read back in 8 bits, with
            // ca quantised on the host) are the full frame's composite made 8-bit, as the lab
            // encodes it
            let (width, height) = (display.composite.width, display.composite.height);
            assert_eq!((width, height), (64, 48));
            assert!(
                crate::image::Rgba8::from_image(&full.composite) == display.composite,
                "ca {ca}, frame {frame}: the composites differ"
            );
            assert!(full.composite.to_rgb8() == display.composite.to_rgb8(), "ca {ca}, frame {frame}: RGB differs");
            assert_eq!(display.report.camera_artifacts.is_some(), ca);
            // the first frame has no history to smooth against; the second does
            assert_eq!((full.report.temporal_smoothing, display.report.temporal_smoothing), (frame > 0, frame > 0));
        }
        assert_eq!(live.temporal.as_ref().map(|t| t.frames), shown.temporal.as_ref().map(|t| t.frames));
    }
}
