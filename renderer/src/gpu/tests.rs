//! Tests of the GPU renderer that need no adapter: every shader parsed and validated by naga,
//! the camera matrix against the CPU camera.

use super::*;

/// Every WGSL file of the GPU renderer, found by walking `src/gpu/` (no list to forget),
/// parsed and validated by naga as the renderer compiles it: with `common.wgsl` in front
/// where the Rust beside it puts it there. A shader no Rust file includes is an error.
#[test]
fn every_shader_parses_and_validates_with_naga() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/gpu");
    let rust: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|extension| extension == "rs"))
        .map(|path| std::fs::read_to_string(path).unwrap())
        .collect();
    let common = std::fs::read_to_string(dir.join("common.wgsl")).unwrap();
    let mut validated = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|extension| extension != "wgsl") {
            continue;
        }
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let own = std::fs::read_to_string(&path).unwrap();
        let include = format!("include_str!(\"{name}\")");
        let lines: Vec<&str> =
            rust.iter().flat_map(|text| text.lines()).filter(|line| line.contains(&include)).collect();
        assert!(!lines.is_empty(), "{name} is included by no Rust file in src/gpu");
        let with_common =
            lines.iter().any(|line| line.contains("include_str!(\"common.wgsl\")")) && name != "common.wgsl";
        let source = if with_common { format!("{common}{own}") } else { own };
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
        "cm.wgsl",
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
