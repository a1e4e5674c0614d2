//! The live renderer of task studies: one dedicated thread owning the one wgpu device
//! ([`DirRenderer`]), fed frame jobs through a channel and answering each with a JPEG.
//!
//! Each task study registers a [`LabScene`]: its scene at the live resolution, with the virtual
//! cube turned to the real cube's orientation, and the photograph of the real scene (CPU path
//! tracer, rendered once and cached as an 8-bit PNG in `<data-dir>/lab/`, so later starts and
//! the first start show the same pixels). A frame job names the study, the condition, the trial,
//! where the virtual cube's centre is, and carries the session's [`SessionRenderState`] in and
//! out: the renderer's [`LiveState`] with the previous frame's indirect light for temporal
//! smoothing (thesis 5.2.9, eqs. 5.11–5.15; `DirRenderer::render_display`, which reads back
//! only the composite, with the passes pipelined) and the colour mapping's history. The history
//! starts afresh with each trial (and each condition), so one trial's light never shows in the
//! next; `smoothing` says whether the last frame reused any.
//!
//! Jobs are rendered in arrival order. A session keeps at most one job in flight and coalesces
//! the inputs that arrive meanwhile into its next job (see [`super::session`]), so a slow
//! adapter shows fewer frames rather than a growing queue.

use std::path::Path;
use std::sync::mpsc;
use std::time::Instant;

use mrstudy_renderer::cm::CmState;
use mrstudy_renderer::coherent::CoherentParams;
use mrstudy_renderer::coherent::render::LiveCoherent;
use mrstudy_renderer::gpu::{DirParams, DirRenderer, GiLevel, LiveState};
use mrstudy_renderer::image::{Image, Rgba8};
use mrstudy_renderer::reference::{ReferenceParams, render_photo};
use mrstudy_renderer::scene::Scene;
use tokio::sync::oneshot;

use super::plan::Layout;
use crate::study::task::{Condition, TaskStudy};

/// The adapter the renderer thread opened.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AdapterInfo {
    /// The adapter's name and backend.
    pub adapter: String,
    /// `hardware`, `software` or `gl`.
    pub kind: String,
}

impl AdapterInfo {
    pub fn is_software(&self) -> bool {
        self.kind != "hardware"
    }
}

/// Per-session renderer state, passed into each frame job and handed back with the frame.
#[derive(Clone, Default)]
pub struct SessionRenderState {
    /// Frames rendered for this session.
    pub frames: u64,
    /// Whether the last frame was smoothed with the one before it (temporal smoothing ran with
    /// a history: the same trial, a `gi` frame with VPLs).
    pub smoothing: bool,
    /// The trial and condition of the last frame; another trial starts a fresh history.
    pub last: Option<(u32, Condition)>,
    /// The renderer's history (GPU buffers); one frame of a session is in flight at a time.
    pub live: std::sync::Arc<std::sync::Mutex<LiveState>>,
    /// The colour mapping's history of a coherent condition's frames.
    pub coherent_cm: CmState,
}

impl std::fmt::Debug for SessionRenderState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionRenderState")
            .field("frames", &self.frames)
            .field("smoothing", &self.smoothing)
            .field("last", &self.last)
            .finish_non_exhaustive()
    }
}

/// One study's scene made ready for live frames.
pub struct LabScene {
    pub slug: String,
    pub scene: Scene,
    /// Shared with the live frames' kept photograph (`DirRenderer::render_display`).
    pub photo: std::sync::Arc<Image>,
    pub virtual_object: String,
    /// The virtual object's centre in `scene` (frames move it from here).
    pub base_centre: glam::Vec3,
    pub layout: Layout,
    pub params: DirParams,
    /// The capture, linear photograph and light probe the coherent conditions render from;
    /// None when the study has none.
    pub coherent: Option<LiveCoherent>,
    pub jpeg_quality: u8,
}

/// A rendered, encoded frame.
#[derive(Debug)]
pub struct Frame {
    pub jpeg: Vec<u8>,
    pub width: u32,
    pub height: u32,
    /// Wall-clock time of the frame on the renderer thread (scene update, all passes, read-back)
    /// and of the JPEG encoding.
    pub render_ms: f64,
    pub encode_ms: f64,
    pub state: SessionRenderState,
}

/// A frame to render.
pub struct FrameJob {
    pub study: String,
    pub condition: Condition,
    /// The trial the frame belongs to (a new trial starts a fresh smoothing history).
    pub trial: u32,
    /// The virtual cube's centre, metres.
    pub centre: [f64; 3],
    pub state: SessionRenderState,
    pub reply: oneshot::Sender<Result<Frame, String>>,
}

enum Request {
    Register(Box<LabScene>),
    Frame(FrameJob),
}

/// The handle of the renderer thread; cheap to clone. When the last handle goes, the thread is
/// told to stop and joined: the frame in flight finishes and the wgpu device is destroyed
/// before the drop returns, so the process never exits while the thread is still inside the
/// driver (lavapipe tears itself down at exit, and a thread still using it then crashes the
/// process).
#[derive(Clone)]
pub struct LabRenderer {
    thread: std::sync::Arc<RendererThread>,
    pub adapter: AdapterInfo,
}

/// The renderer thread's channel and join handle, shared by every [`LabRenderer`] handle.
struct RendererThread {
    sender: Option<mpsc::Sender<Request>>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl RendererThread {
    fn send(&self, request: Request) -> Result<(), LiveError> {
        self.sender.as_ref().ok_or(LiveError::Stopped)?.send(request).map_err(|_| LiveError::Stopped)
    }
}

impl Drop for RendererThread {
    fn drop(&mut self) {
        // Closing the channel ends the thread's loop once the job in flight is answered.
        drop(self.sender.take());
        if let Some(handle) = self.handle.take()
            && handle.join().is_err()
        {
            tracing::error!("the lab renderer thread panicked");
        }
    }
}

impl LabRenderer {
    /// Starts the renderer thread and opens the GPU on it; the error says why no adapter could
    /// be opened.
    pub fn start() -> Result<LabRenderer, LiveError> {
        let (sender, receiver) = mpsc::channel::<Request>();
        let (ready, started) = mpsc::channel::<Result<AdapterInfo, LiveError>>();
        let handle = std::thread::Builder::new()
            .name("mrstudy-lab-renderer".into())
            .spawn(move || {
                let renderer = match DirRenderer::new() {
                    Ok(renderer) => renderer,
                    Err(error) => {
                        let _ = ready.send(Err(LiveError::NoAdapter { reason: error.to_string() }));
                        return;
                    }
                };
                // frames pipelined: passes are only submitted, and the frame waits where it
                // needs data back (the drawn VPLs, the composite); nothing here reads pass times
                renderer.ctx.set_pass_waits(false);
                let info = &renderer.ctx.info;
                let _ = ready.send(Ok(AdapterInfo {
                    adapter: format!("{} ({:?})", info.name, info.backend),
                    kind: renderer.ctx.kind.to_string(),
                }));
                run(renderer, receiver);
            })
            .map_err(|error| LiveError::Thread { reason: error.to_string() })?;
        let thread = std::sync::Arc::new(RendererThread { sender: Some(sender), handle: Some(handle) });
        let adapter = started.recv().map_err(|_| LiveError::StoppedOpening)??;
        Ok(LabRenderer { thread, adapter })
    }

    /// Hands a prepared scene to the renderer thread.
    pub fn register(&self, scene: LabScene) -> Result<(), LiveError> {
        self.thread.send(Request::Register(Box::new(scene)))
    }

    /// Queues a frame; the answer comes on `job.reply`.
    pub fn submit(&self, job: FrameJob) -> Result<(), LiveError> {
        self.thread.send(Request::Frame(job))
    }

    /// Renders one frame and waits for it.
    pub async fn frame(
        &self,
        study: &str,
        condition: Condition,
        trial: u32,
        centre: [f64; 3],
        state: SessionRenderState,
    ) -> Result<Frame, LiveError> {
        let (reply, answer) = oneshot::channel();
        self.submit(FrameJob { study: study.to_string(), condition, trial, centre, state, reply })?;
        answer
            .await
            .map_err(|_| LiveError::StoppedDuringFrame)?
            .map_err(|reason| LiveError::Frame { study: study.to_string(), reason })
    }
}

fn run(renderer: DirRenderer, receiver: mpsc::Receiver<Request>) {
    let mut scenes: Vec<LabScene> = Vec::new();
    while let Ok(request) = receiver.recv() {
        match request {
            Request::Register(scene) => {
                scenes.retain(|other| other.slug != scene.slug);
                scenes.push(*scene);
            }
            Request::Frame(job) => {
                let result = match scenes.iter().find(|scene| scene.slug == job.study) {
                    Some(lab) => render_frame(&renderer, lab, &job),
                    None => Err(format!("no live scene is registered for study \"{}\"", job.study)),
                };
                let _ = job.reply.send(result);
            }
        }
    }
}

fn render_frame(renderer: &DirRenderer, lab: &LabScene, job: &FrameJob) -> Result<Frame, String> {
    let centre = glam::DVec3::from(job.centre).as_vec3();
    if !centre.is_finite() {
        return Err("the virtual cube's position is not finite".into());
    }
    let mut scene = lab.scene.clone();
    scene.translate_object(&lab.virtual_object, centre - lab.base_centre);
    let mut state = job.state.clone();
    let fresh = state.last != Some((job.trial, job.condition));
    let render_start = Instant::now();
    let (composite, smoothing) = match job.condition {
        Condition::Dir(level) => {
            let params = DirParams { condition: level, ..lab.params.clone() };
            let mut live = state.live.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            if fresh {
                *live = LiveState::default();
            }
            // only the composite is read back, in 8 bits: the lab shows it and nothing else
            let render =
                renderer.render_display(&scene, &lab.photo, &params, &mut live).map_err(|error| error.to_string())?;
            (render.composite, render.report.temporal_smoothing)
        }
        Condition::Coherent(level) => {
            let Some(coherent) = &lab.coherent else {
                return Err(format!("study \"{}\" was prepared without its coherent conditions", lab.slug));
            };
            if fresh {
                state.coherent_cm = CmState::default();
            }
            // the same random numbers every frame: a still cube shows a still picture
            let params = CoherentParams::new(level.method, level.quality);
            // lavapipe builds the representations slower than the CPU (issue 18's note)
            let gpu = (renderer.ctx.kind == mrstudy_renderer::gpu::context::AdapterKind::Hardware).then_some(renderer);
            let frame = coherent
                .frame(&scene, &params, &lab.params.cm, &mut state.coherent_cm, gpu)
                .map_err(|error| error.to_string())?;
            (Rgba8::from_image(&frame.composite), false)
        }
    };
    let render_ms = render_start.elapsed().as_secs_f64() * 1e3;
    let encode_start = Instant::now();
    let jpeg = encode_jpeg(&composite, lab.jpeg_quality).map_err(|error| error.to_string())?;
    let encode_ms = encode_start.elapsed().as_secs_f64() * 1e3;
    state.frames += 1;
    state.last = Some((job.trial, job.condition));
    state.smoothing = smoothing;
    Ok(Frame { jpeg, width: composite.width, height: composite.height, render_ms, encode_ms, state })
}

/// A display-encoded frame in 8 bits as baseline JPEG (of its RGB: the bytes
/// `Image::to_rgb8` gives the image it was quantised from).
pub fn encode_jpeg(frame: &Rgba8, quality: u8) -> Result<Vec<u8>, LiveError> {
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality.clamp(1, 100))
        .encode(&frame.to_rgb8(), frame.width, frame.height, image::ExtendedColorType::Rgb8)
        .map_err(|error| LiveError::Jpeg { reason: error.to_string() })?;
    Ok(bytes)
}

/// Why the lab's renderer could not start, take a scene or a frame, or encode one; or why a
/// task study's scene could not be prepared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LiveError {
    /// No GPU adapter could be opened: the renderer's reason.
    #[error("{reason}")]
    NoAdapter { reason: String },
    #[error("cannot start the renderer thread: {reason}")]
    Thread { reason: String },
    #[error("the renderer thread stopped while opening the GPU")]
    StoppedOpening,
    #[error("the renderer thread has stopped")]
    Stopped,
    #[error("the renderer thread stopped during a frame")]
    StoppedDuringFrame,
    /// A frame of study `study` could not be rendered: the renderer's reason.
    #[error("{reason}")]
    Frame { study: String, reason: String },
    #[error("cannot encode a frame as JPEG: {reason}")]
    Jpeg { reason: String },
    /// Task study `study`'s scene or photograph could not be prepared: `reason` is the sentence,
    /// which names the study, the scene file or the cache file at fault.
    #[error("{reason}")]
    Scene { study: String, reason: String },
}

/// Loads a task study's scene at the live size `size` (see [`super::size`]), turns the virtual
/// cube to the real cube's orientation, and renders (or reads from the cache under `cache_dir`)
/// its photograph; without a cache directory the photograph is rendered and not stored (the
/// start-up size ladder's scenes).
pub fn prepare_scene(study: &TaskStudy, size: [u32; 2], cache_dir: Option<&Path>) -> Result<LabScene, LiveError> {
    scene_of(study, size, cache_dir).map_err(|reason| LiveError::Scene { study: study.slug.clone(), reason })
}

fn scene_of(study: &TaskStudy, size: [u32; 2], cache_dir: Option<&Path>) -> Result<LabScene, String> {
    let context = |what: &str| format!("study \"{}\": {what}", study.slug);
    let mut desc = match mrstudy_renderer::builtin::get(&study.scene) {
        Some(desc) => desc,
        None => {
            let text = std::fs::read_to_string(&study.scene)
                .map_err(|error| context(&format!("cannot read scene file {}: {error}", study.scene)))?;
            mrstudy_renderer::scene::SceneDesc::from_toml(&text, &study.scene)
                .map_err(|error| context(&error.to_string()))?
        }
    };
    let real_rotation = desc.objects.iter().find(|o| o.name == study.real_object).map(|o| o.rotate_deg);
    let Some(real_rotation) = real_rotation else {
        return Err(context(&format!(
            "scene \"{}\" has no object named \"{}\" (scene.real_object)",
            study.scene, study.real_object
        )));
    };
    let Some(virtual_desc) = desc.objects.iter_mut().find(|o| o.name == study.virtual_object) else {
        return Err(context(&format!(
            "scene \"{}\" has no object named \"{}\" (scene.virtual_object)",
            study.scene, study.virtual_object
        )));
    };
    virtual_desc.rotate_deg = real_rotation;
    let [width, height] = size;
    let base = Path::new(&study.scene).parent().unwrap_or(Path::new("."));
    let scene = Scene::from_desc(desc, base, &study.scene)
        .map_err(|error| context(&error.to_string()))?
        .with_size(width, height);
    let real = scene
        .objects
        .iter()
        .find(|o| o.name == study.real_object)
        .ok_or_else(|| context("the real object vanished"))?;
    if real.role != mrstudy_renderer::scene::Role::Real {
        return Err(context(&format!("object \"{}\" is not real (scene.real_object)", study.real_object)));
    }
    let virtual_object = scene
        .objects
        .iter()
        .find(|o| o.name == study.virtual_object)
        .ok_or_else(|| context("the virtual object vanished"))?;
    if virtual_object.role != mrstudy_renderer::scene::Role::Virtual {
        return Err(context(&format!("object \"{}\" is not virtual (scene.virtual_object)", study.virtual_object)));
    }
    let real_centre =
        scene.object_centre(&study.real_object).ok_or_else(|| context("the real object has no geometry"))?;
    let base_centre =
        scene.object_centre(&study.virtual_object).ok_or_else(|| context("the virtual object has no geometry"))?;
    let half = f64::from(real_centre.y);
    let layout = Layout {
        real_centre: real_centre.as_dvec3().to_array(),
        half_height: half,
        reach: reach(&scene.camera, real_centre.as_dvec3(), half),
    };
    let coherent_conditions = study.conditions.iter().any(|c| matches!(c, Condition::Coherent(_)));
    let (photo, linear) = cached_photo(&scene, study, cache_dir, coherent_conditions)?;
    let coherent = match linear {
        Some(linear) => Some(
            LiveCoherent::new(&scene, photo.clone(), linear, COHERENT_SEED)
                .map_err(|error| context(&format!("cannot capture the scene for the coherent conditions: {error}")))?,
        ),
        None => None,
    };
    Ok(LabScene {
        slug: study.slug.clone(),
        scene,
        photo: std::sync::Arc::new(photo),
        virtual_object: study.virtual_object.clone(),
        base_centre,
        layout,
        params: DirParams {
            condition: GiLevel::Gi,
            vpls: study.render.vpls,
            shadow_map_size: study.render.shadow_map_size,
            env_lights: study.render.env_lights,
            // live frames: small RSMs, few environment directions for the VPLs and small ISMs
            // (the stimuli's 128² RSMs along 8 directions and 128² ISMs of 1024 points made a
            // 160×120 frame of the lab scene take 290 ms on lavapipe)
            rsm_size: 32,
            env_vpl_directions: 2,
            ism_size: 32,
            ism_points: 256,
            // one bounce: the multiple-bounce light source's search (two further bounces over
            // 4096 candidates per slot) would add about 60 ms a frame on lavapipe
            bounces: 1,
            ..DirParams::default()
        },
        coherent,
        jpeg_quality: study.render.jpeg_quality,
    })
}

/// The seed of the live coherent conditions' capture and light probe.
const COHERENT_SEED: u64 = 1;

/// How far (m, up to 0.30) the virtual cube can move from the real one towards −x, +x, −z and
/// +z with every corner — up to 10 cm above the table for the contact task — inside the image
/// with a 3 % margin.
fn reach(camera: &mrstudy_renderer::camera::Camera, real: glam::DVec3, half: f64) -> [f64; 4] {
    let (width, height) = (camera.width as f32, camera.height as f32);
    let (mx, my) = (0.03 * width, 0.03 * height);
    let visible = |centre: glam::DVec3| {
        [-1.0, 1.0].iter().all(|&sx: &f64| {
            [-1.0, 1.0].iter().all(|&sz: &f64| {
                [-half, half + 0.10].iter().all(|&dy| {
                    let corner = (centre + glam::DVec3::new(sx * half, dy, sz * half)).as_vec3();
                    camera
                        .project(corner)
                        .is_some_and(|(px, py)| px >= mx && px <= width - mx && py >= my && py <= height - my)
                })
            })
        })
    };
    let directions = [-glam::DVec3::X, glam::DVec3::X, -glam::DVec3::Z, glam::DVec3::Z];
    directions.map(|direction| {
        let mut reach = 0.0;
        let mut distance = 0.005;
        while distance <= 0.30 + 1e-9 && visible(real + direction * distance) {
            reach = distance;
            distance += 0.005;
        }
        reach
    })
}

/// The photograph of the real scene at the live size (display-encoded) and, with `linear`, its
/// linear radiance (for the coherent conditions), from `cache_dir` when they are there (named
/// by a hash of the scene description, size and samples; the photograph as PNG, its radiance
/// as EXR), else path-traced and stored.
fn cached_photo(
    scene: &Scene,
    study: &TaskStudy,
    cache_dir: Option<&Path>,
    linear: bool,
) -> Result<(Image, Option<Image>), String> {
    let Some(cache_dir) = cache_dir else {
        let params = ReferenceParams { spp: study.render.photo_spp, ..ReferenceParams::default() };
        let (hdr, photo, _) = render_photo(scene, &params, &|_, _| {})
            .map_err(|error| format!("study \"{}\": cannot render the photograph: {error}", study.slug))?;
        let bytes = photo.to_rgb8();
        return Ok((Image::from_rgb8(photo.width, photo.height, &bytes), linear.then_some(hdr)));
    };
    let key = crate::study::sha256_hex(
        format!("{}\n{}x{}\n{}", scene.desc.to_toml(), scene.camera.width, scene.camera.height, study.render.photo_spp)
            .as_bytes(),
    );
    let (width, height) = (scene.camera.width, scene.camera.height);
    let stem = format!("photo-{}-{width}x{height}-{}", study.slug, &key[..16]);
    let path = cache_dir.join(format!("{stem}.png"));
    let exr = cache_dir.join(format!("{stem}.exr"));
    let cached_png = image::open(&path)
        .ok()
        .map(|image| image.into_rgb8())
        .filter(|rgb| rgb.width() == width && rgb.height() == height)
        .map(|rgb| Image::from_rgb8(width, height, rgb.as_raw()));
    let cached_exr = || {
        Image::load(&exr, "the photograph's radiance")
            .ok()
            .filter(|image| (image.width, image.height) == (width, height))
    };
    match (cached_png, linear) {
        (Some(photo), false) => return Ok((photo, None)),
        (Some(photo), true) => {
            if let Some(radiance) = cached_exr() {
                return Ok((photo, Some(radiance)));
            }
        }
        (None, _) => {}
    }
    let params = ReferenceParams { spp: study.render.photo_spp, ..ReferenceParams::default() };
    let (hdr, photo, _) = render_photo(scene, &params, &|_, _| {})
        .map_err(|error| format!("study \"{}\": cannot render the photograph: {error}", study.slug))?;
    let bytes = photo.to_rgb8();
    std::fs::create_dir_all(cache_dir).map_err(|error| format!("cannot create {}: {error}", cache_dir.display()))?;
    // written under a temporary name and renamed, so a crash never leaves half a file
    let temporary = cache_dir.join(format!(".{key}.partial.exr"));
    hdr.save_exr(&temporary)
        .map_err(|error| error.to_string())
        .and_then(|_| std::fs::rename(&temporary, &exr).map_err(|error| error.to_string()))
        .map_err(|error| format!("cannot write the photograph cache {}: {error}", exr.display()))?;
    let temporary = cache_dir.join(format!(".{key}.partial.png"));
    image::save_buffer(&temporary, &bytes, photo.width, photo.height, image::ExtendedColorType::Rgb8)
        .and_then(|_| std::fs::rename(&temporary, &path).map_err(image::ImageError::IoError))
        .map_err(|error| format!("cannot write the photograph cache {}: {error}", path.display()))?;
    Ok((Image::from_rgb8(photo.width, photo.height, &bytes), linear.then_some(hdr)))
}

/// Frame-time measurement at start-up: after one warm-up frame, renders `frames` frames of the
/// study's scene under each of its conditions as a participant would see them — in two trials,
/// each starting afresh, with the virtual cube moving 1 cm between frames (a moved cube costs
/// the gi condition more than a still one) — and returns each condition's render plus encode
/// times in ms, in the study's order.
pub async fn measure(
    renderer: &LabRenderer,
    study: &TaskStudy,
    centre: [f64; 3],
    frames: usize,
) -> Result<Vec<(Condition, Vec<f64>)>, LiveError> {
    let mut measured = Vec::new();
    for (index, &condition) in study.conditions.iter().enumerate() {
        let mut state = SessionRenderState::default();
        let mut times = Vec::new();
        // trial numbers past any schedule, two per condition, so each starts a fresh history
        let trials = [u32::MAX - 2 * index as u32, u32::MAX - 2 * index as u32 - 1];
        for frame_index in 0..=frames.max(1) {
            let trial = if frame_index <= frames / 2 { trials[0] } else { trials[1] };
            let position = [centre[0] - 0.01 * frame_index as f64, centre[1], centre[2]];
            let frame = renderer.frame(&study.slug, condition, trial, position, state).await?;
            // a participant's frames come with pauses between them (keys, pacing), after which
            // the renderer is slower than back to back (threads and caches gone cold)
            tokio::time::sleep(std::time::Duration::from_secs_f64((frame.render_ms + frame.encode_ms).max(5.0) / 1e3))
                .await;
            if frame_index > 0 {
                times.push(frame.render_ms + frame.encode_ms);
            }
            state = frame.state;
        }
        measured.push((condition, times));
    }
    Ok(measured)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ids of this process's threads named like the renderer thread (Linux keeps a thread
    /// name's first 15 bytes; the driver's threads started from it inherit the name).
    fn renderer_named_threads() -> Vec<u64> {
        let Ok(tasks) = std::fs::read_dir("/proc/self/task") else { return Vec::new() };
        let mut ids: Vec<u64> = tasks
            .filter_map(|task| {
                let path = task.ok()?.path();
                let name = std::fs::read_to_string(path.join("comm")).ok()?;
                (name.trim() == "mrstudy-lab-ren").then(|| path.file_name()?.to_str()?.parse().ok())?
            })
            .collect();
        ids.sort_unstable();
        ids
    }

    #[test]
    fn the_renderer_thread_has_ended_when_the_last_handle_is_dropped() {
        if !Path::new("/proc/self/task").exists() {
            eprintln!("skipping: no /proc/self/task to list threads");
            return;
        }
        let before = renderer_named_threads();
        let renderer = match LabRenderer::start() {
            Ok(renderer) => renderer,
            Err(error) => {
                eprintln!("skipping: no GPU adapter: {error}");
                return;
            }
        };
        // The renderer thread started before the driver's threads it spawned: the lowest new id.
        let thread = renderer_named_threads().into_iter().find(|id| !before.contains(id));
        let thread = thread.expect("the renderer thread runs");
        let other = renderer.clone();
        drop(renderer);
        assert!(renderer_named_threads().contains(&thread), "a handle is left: the thread still runs");
        drop(other);
        assert!(!renderer_named_threads().contains(&thread), "the drop of the last handle joined the thread");
    }
}
