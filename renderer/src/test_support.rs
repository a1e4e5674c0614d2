//! Support shared by the renderer's unit tests: one builder of the small TOML test scenes, one
//! GPU renderer per test binary with the skip-if-no-adapter rule (a skipped test says which and
//! why), and an image comparison that writes the actual, expected and difference images when it
//! fails and names their paths.

use crate::gpu::DirRenderer;
use crate::image::Image;
use crate::scene::{Scene, SceneDesc};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A test scene configuration: a camera looking at the origin from (0, 0.7, 0.9), a real floor
/// plane, named materials, extra objects (TOML `[[objects]]` tables) and a real spot light from
/// above and the side. [`TestScene::new`] gives the GPU tests' scene (128×96, materials `floor`,
/// `white`, `red`, spot cone 35°/45°).
pub(crate) struct TestScene {
    name: String,
    width: u32,
    height: u32,
    /// (name, albedo as TOML), in the order written.
    materials: Vec<(String, String)>,
    objects: String,
    spot_cone_deg: (u32, u32),
}

impl TestScene {
    pub(crate) fn new(name: &str) -> TestScene {
        TestScene {
            name: name.to_string(),
            width: 128,
            height: 96,
            materials: [("floor", "0.6"), ("white", "0.8"), ("red", "[0.8, 0.05, 0.05]")]
                .iter()
                .map(|(name, albedo)| (name.to_string(), albedo.to_string()))
                .collect(),
            objects: String::new(),
            spot_cone_deg: (35, 45),
        }
    }

    pub(crate) fn size(mut self, width: u32, height: u32) -> TestScene {
        (self.width, self.height) = (width, height);
        self
    }

    /// Replaces the materials: (name, albedo as TOML, e.g. `0.8` or `[0.8, 0.1, 0.08]`).
    pub(crate) fn materials(mut self, materials: &[(&str, &str)]) -> TestScene {
        self.materials = materials.iter().map(|(name, albedo)| (name.to_string(), albedo.to_string())).collect();
        self
    }

    /// Appends objects written as TOML `[[objects]]` tables.
    pub(crate) fn objects(mut self, objects: &str) -> TestScene {
        self.objects.push_str(objects);
        self
    }

    /// The spot light's inner and outer cone angles in degrees.
    pub(crate) fn spot_cone(mut self, inner_deg: u32, outer_deg: u32) -> TestScene {
        self.spot_cone_deg = (inner_deg, outer_deg);
        self
    }

    /// The scene file's text.
    pub(crate) fn toml(&self) -> String {
        let TestScene { name, width, height, materials, objects, spot_cone_deg: (inner, outer) } = self;
        let materials: String =
            materials.iter().map(|(name, albedo)| format!("[materials.{name}]\nalbedo = {albedo}\n")).collect();
        format!(
            r#"
name = "{name}"
[camera]
width = {width}
height = {height}
fov_y_deg = 50
position = [0.0, 0.7, 0.9]
look_at = [0.0, 0.0, 0.0]
[camera.sensor]
preset = "clean"
{materials}[[objects]]
name = "floor"
role = "real"
shape = "plane"
size = [3.0, 3.0]
material = "floor"
{objects}
[[lights]]
kind = "spot"
position = [0.35, 0.9, 0.35]
target = [0.0, 0.0, 0.0]
inner_deg = {inner}
outer_deg = {outer}
intensity = 1.0
"#
        )
    }

    pub(crate) fn build(&self) -> Scene {
        let file = format!("{}.toml", self.name);
        let desc = SceneDesc::from_toml(&self.toml(), &file).unwrap_or_else(|e| panic!("{e}\n{}", self.toml()));
        Scene::from_desc(desc, Path::new("."), &file).unwrap()
    }
}

/// A scene from a test's own scene-file text, named `name` (a parse error panics with the text).
pub(crate) fn scene_from_toml(text: &str, name: &str) -> Scene {
    let desc = SceneDesc::from_toml(text, &format!("{name}.toml")).unwrap_or_else(|e| panic!("{e}\n{text}"));
    Scene::from_desc(desc, Path::new("."), name).unwrap()
}

/// The capture set-up the capture and coherent tests share: `scene`'s real world and capture
/// parameters for `poses` poses from its camera, `colour_spp` colour samples per pixel and a
/// hash grid of `grid_capacity` samples.
pub(crate) fn capture_setup(
    scene: &Scene,
    poses: usize,
    colour_spp: u32,
    grid_capacity: usize,
) -> (crate::pathtracer::World, crate::capture::CaptureParams) {
    let real = crate::pathtracer::World::new(scene, crate::pathtracer::Subset::RealOnly);
    let mut params = crate::capture::CaptureParams::for_scene(scene, &real, poses);
    params.colour_spp = colour_spp;
    params.grid_capacity = grid_capacity;
    (real, params)
}

/// The coherent tests' capture of `scene`: two poses, 4 colour samples per pixel, a grid cell of
/// `cell` metres; its real world and the environment samples the grid kept.
pub(crate) fn captured_samples(
    scene: &Scene,
    cell: f32,
) -> (crate::pathtracer::World, Vec<crate::capture::hashgrid::EnvironmentSample>) {
    let (real, mut params) = capture_setup(scene, 2, 4, 1 << 16);
    params.cell = cell;
    let samples = crate::capture::capture(&real, &params, |_, _| {}).grid.samples().copied().collect();
    (real, samples)
}

/// The GPU tests' scene ([`TestScene::new`]) with extra objects.
pub(crate) fn scene_with(objects: &str) -> Scene {
    TestScene::new("gpu-test").objects(objects).build()
}

/// One box as a TOML `[[objects]]` table; `role` is `real` or `virtual`.
pub(crate) fn box_object(name: &str, role: &str, size: [f32; 3], translate: [f32; 3], material: &str) -> String {
    format!(
        "[[objects]]\nname = \"{name}\"\nrole = \"{role}\"\nshape = \"box\"\nsize = {size:?}\ntranslate = \
         {translate:?}\nmaterial = \"{material}\"\n"
    )
}

/// The tests' one GPU renderer (one device, shaders compiled once per test binary), or why none
/// opened.
pub(crate) fn dir_renderer() -> Result<&'static DirRenderer, &'static str> {
    static RENDERER: OnceLock<Result<DirRenderer, String>> = OnceLock::new();
    RENDERER
        .get_or_init(|| match DirRenderer::new() {
            Ok(renderer) => {
                eprintln!("GPU tests on {}", renderer.ctx.adapter_name());
                Ok(renderer)
            }
            Err(e) => Err(e.to_string()),
        })
        .as_ref()
        .map_err(String::as_str)
}

/// The shared GPU renderer; `None` when no adapter opens, after printing which test skips and
/// why. A GPU test starts `let Some(renderer) = renderer_or_skip() else { return };`.
pub(crate) fn renderer_or_skip() -> Option<&'static DirRenderer> {
    match dir_renderer() {
        Ok(renderer) => Some(renderer),
        Err(why) => {
            let thread = std::thread::current();
            eprintln!("skipping {}: no GPU adapter opens ({why})", thread.name().unwrap_or("a GPU test"));
            None
        }
    }
}

/// A grey (0.5) photograph of the scene's size.
pub(crate) fn grey_photo(scene: &Scene) -> Image {
    Image::filled(scene.camera.width, scene.camera.height, Vec3::splat(0.5))
}

/// Where failing image tests write their images: the test target's temporary folder where Cargo
/// names one, else the system's.
fn image_dir() -> PathBuf {
    let base = option_env!("CARGO_TARGET_TMPDIR").map(PathBuf::from).unwrap_or_else(std::env::temp_dir);
    base.join("mrstudy-renderer-image-tests")
}

/// The largest per-channel difference of two images of one size (NaN where any channel is NaN on
/// one side only, or where the two differ in an infinity).
fn channel_difference(a: Vec3, b: Vec3) -> f32 {
    (0..3)
        .map(|k| if a[k] == b[k] { 0.0 } else { (a[k] - b[k]).abs() })
        .fold(0.0, |worst: f32, d| if d.is_nan() || worst.is_nan() { f32::NAN } else { worst.max(d) })
}

/// Asserts that `actual` matches `expected`: same size, and every channel within `tolerance`
/// (exactly equal when it is 0) at all but `outlier_fraction` of the pixels (a NaN is always an
/// outlier). On failure writes `<name>-actual.png`, `<name>-expected.png` and
/// `<name>-difference.png` (|actual − expected| per channel, the largest difference white) and
/// names them in the panic message.
pub(crate) fn assert_images_match(name: &str, actual: &Image, expected: &Image, tolerance: f32, outlier_fraction: f32) {
    assert_eq!(
        (actual.width, actual.height),
        (expected.width, expected.height),
        "{name}: the actual image's size differs from the expected one's"
    );
    let differences: Vec<f32> =
        actual.pixels.iter().zip(&expected.pixels).map(|(a, b)| channel_difference(*a, *b)).collect();
    let outliers = differences.iter().filter(|d| !(**d <= tolerance)).count();
    if outliers as f64 <= f64::from(outlier_fraction) * differences.len() as f64 {
        return;
    }
    let worst = differences.iter().copied().filter(|d| d.is_finite()).fold(0.0, f32::max);
    let mut difference = Image::new(actual.width, actual.height);
    for (pixel, (a, b)) in difference.pixels.iter_mut().zip(actual.pixels.iter().zip(&expected.pixels)) {
        let d = (*a - *b).abs();
        *pixel = if d.is_finite() && worst > 0.0 { d / worst } else { Vec3::ONE };
    }
    let dir = image_dir();
    let written = std::fs::create_dir_all(&dir).map_err(|e| e.to_string()).and_then(|()| {
        let mut paths = Vec::new();
        for (suffix, image) in [("actual", actual), ("expected", expected), ("difference", &difference)] {
            let path = dir.join(format!("{name}-{suffix}.png"));
            image.save_png(&path).map_err(|e| e.to_string())?;
            paths.push(path.display().to_string());
        }
        Ok(paths.join(", "))
    });
    let written = match written {
        Ok(paths) => format!("images written: {paths}"),
        Err(e) => format!("the images could not be written to {}: {e}", dir.display()),
    };
    panic!(
        "{name}: {outliers} of {} pixels differ by more than {tolerance} (at most {outlier_fraction} of them may), \
         largest finite difference {worst}; {written}",
        differences.len()
    );
}
