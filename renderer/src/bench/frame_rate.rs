//! `bench render --frame-rate`: the thesis's real-time settings at its resolution, frames
//! rendered back to back, for a hardware GPU. Per scene and condition: the median, 10th and
//! 90th percentile of the whole frame's wall-clock time (upload, every pass, the read-back of
//! the composite — what a stimulus or a live lab frame costs) and its rate, and each pass's
//! median time.
//!
//! The settings are the thesis's: 256 VPLs, 128² ISMs of 1024 points, 4×4 interleaved sampling
//! at 1024×768 (5.2, 13–18 fps on a GTX 580); in scenes with mirrors or glass also 512² caustic
//! maps (5.3: the glass bunny at 13 fps). No ground truth is rendered: the error of these
//! settings at a size the path tracer reaches is in `bench render` (DIR rows and the specular
//! rows).
//!
//! Every pass is timed by waiting for the device after it (`timed` in [`crate::gpu`]), so a
//! frame of the first series is a sum of synchronised passes; on a hardware adapter with
//! timestamp queries each pass also reports the GPU's own time in its command buffers
//! (`gpu_ms`, see [`crate::gpu::context::GpuContext::submit`]), so a pass's host work and
//! waiting is the difference. A second series renders the same
//! frames pipelined ([`crate::gpu::context::GpuContext::set_pass_waits`] off: passes only submitted,
//! the frame waiting where it needs data back) — the frame rate the renderer reaches as built,
//! with the same images. A third renders them as the lab's live frames: pipelined, only the
//! composite read back (`DirRenderer::render_display`), temporal smoothing from frame to frame.

use std::time::Instant;

use serde::Serialize;

use super::{Observer, Report, load_sized};
use crate::error::Result;
use crate::gpu::context::FrameCounters;
use crate::gpu::ism::IsmSplatting;
use crate::gpu::{DirParams, DirRenderer, GiLevel, PassTime, specular::SpecularParams};
use crate::reference::{ReferenceParams, render_photo};

/// One scene and condition rendered back to back.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRateRow {
    pub scene: String,
    pub condition: GiLevel,
    pub width: u32,
    pub height: u32,
    pub vpls: u32,
    pub ism_size: u32,
    pub ism_points: u32,
    /// How the ISMs were splatted (gi rows only): every scene has a gi row of each, so one run
    /// compares the compute pass with the rasteriser on the same machine.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ism_splatting: Option<IsmSplatting>,
    pub interleave: u32,
    /// 0 where the scene has no mirror or glass (no caustic maps run).
    pub caustic_map_size: u32,
    /// Frames timed (after two untimed ones that compile pipelines and warm caches).
    pub frames: u32,
    pub median_ms: f64,
    pub p10_ms: f64,
    pub p90_ms: f64,
    /// 1000 / median_ms.
    pub fps: f64,
    /// The same frames pipelined (no wait after each pass): median, 10th and 90th percentile.
    pub pipelined_median_ms: f64,
    pub pipelined_p10_ms: f64,
    pub pipelined_p90_ms: f64,
    /// 1000 / pipelined_median_ms.
    pub pipelined_fps: f64,
    /// The lab's live frames: pipelined, shown only (`DirRenderer::render_display`: the
    /// composite read back, not L_rv and L_r), temporal smoothing carried from frame to frame:
    /// median, 10th and 90th percentile.
    pub live_median_ms: f64,
    pub live_p10_ms: f64,
    pub live_p90_ms: f64,
    /// 1000 / live_median_ms.
    pub live_fps: f64,
    /// The sum of the passes' medians: what the passes account for of the median frame (the
    /// rest: allocations, bind groups and the like outside the timed passes).
    pub passes_ms: f64,
    /// The sum of the passes' GPU medians (their `gpu_ms`; passes on the CPU have none): how
    /// much of the frame is the GPU's own work. Absent where the context takes no GPU times (a
    /// software adapter, or one without timestamp queries).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_ms: Option<f64>,
    /// MB of GPU buffers and textures ([`crate::gpu::pool`]) the row's first frame made anew
    /// (after the row before it: what a change of scene or condition allocates), and what the
    /// last timed frame made anew and took reused from the pool (0 new: nothing allocated once
    /// a frame of the row has run).
    pub first_frame_new_mb: f64,
    pub new_mb: f64,
    pub reused_mb: f64,
    /// The frame's structure, counted by the renderer itself ([`FrameCounters`]), per series:
    /// the frames timed pass by pass, the pipelined frames and the live (shown) frames. Counts
    /// are medians over the series' frames except `allocations`, the most any frame of the
    /// series made anew (0: nothing allocated after the warm-up frames); `cpu_ms`, `wait_ms`,
    /// `record_ms`, `submit_ms` and `host_steps_ms` are medians (each on its own: they need not
    /// add up).
    pub counters: FrameCounters,
    pub pipelined_counters: FrameCounters,
    pub live_counters: FrameCounters,
    /// Each pass's median over the timed frames, in the frame's order (with its GPU time's
    /// median, `gpu_ms`, where the context takes GPU times).
    pub passes: Vec<PassTime>,
}

/// The counters of a series of frames: medians of the counts and times, the most allocations.
pub fn summarise(frames: &[FrameCounters]) -> FrameCounters {
    let median = |f: &dyn Fn(&FrameCounters) -> f64| quantile(&mut frames.iter().map(f).collect::<Vec<_>>(), 0.5);
    FrameCounters {
        submits: median(&|c| c.submits as f64) as u64,
        encoders: median(&|c| c.encoders as f64) as u64,
        host_waits: median(&|c| c.host_waits as f64) as u64,
        readback_bytes: median(&|c| c.readback_bytes as f64) as u64,
        upload_bytes: median(&|c| c.upload_bytes as f64) as u64,
        allocations: frames.iter().map(|c| c.allocations).max().unwrap_or(0),
        cpu_ms: median(&|c| c.cpu_ms),
        wait_ms: median(&|c| c.wait_ms),
        record_ms: median(&|c| c.record_ms),
        submit_ms: median(&|c| c.submit_ms),
        host_steps_ms: median(&|c| c.host_steps_ms),
    }
}

/// The scenes measured by default: DIR's thesis scene, the glass figure and the metal bottle.
pub const SCENES: [&str; 3] = ["dir-lamp-box", "glass-figure", "metal-bottle"];

/// Runs the benchmark on `scene_name` (default: [`SCENES`]); `quick`: 160×120 and 3 frames
/// (a check that it runs, not a measurement).
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<FrameRateRow>> {
    let names: Vec<String> = match scene_name {
        Some(name) => vec![name.to_string()],
        None => SCENES.iter().map(|s| s.to_string()).collect(),
    };
    let (width, height, frames) = if quick { (160, 120, 3) } else { (1024, 768, 30) };
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    observer.note(&format!("bench render --frame-rate on {adapter}: {width}×{height}, {frames} frames per row"));
    observer.line(&format!(
        "{:<14} {:<8} {:>9} {:>9} {:>9} {:>8} {:>12} {:>8} {:>8} {:>8} {}   slowest passes (median ms)",
        "scene",
        "cond",
        "median ms",
        "p10 ms",
        "p90 ms",
        "fps",
        "pipelined ms",
        "fps",
        "live ms",
        "fps",
        FrameCounters::HEADER
    ));
    let mut rows = Vec::new();
    for name in &names {
        let scene = load_sized(name, width, height)?;
        observer.note(&format!("{name}: the photograph at {width}×{height} (1 spp, path traced)"));
        let (_, photo, _) =
            render_photo(&scene, &ReferenceParams { spp: 1, ..ReferenceParams::default() }, &|_, _| {})?;
        // shared, as the lab shares it: a live frame given the same one compares none of it
        let photo = std::sync::Arc::new(photo);
        let specular = scene.specular_object().is_some();
        let rows_of_scene = [
            (GiLevel::None, IsmSplatting::Compute),
            (GiLevel::Shadows, IsmSplatting::Compute),
            (GiLevel::Gi, IsmSplatting::Compute),
            (GiLevel::Gi, IsmSplatting::Raster),
        ];
        for (condition, ism_splatting) in rows_of_scene {
            let params = DirParams {
                condition,
                vpls: 256,
                ism_size: 128,
                ism_points: 1024,
                ism_splatting,
                interleave: 4,
                specular: SpecularParams { caustic_map_size: 512, ..SpecularParams::default() },
                ..DirParams::default()
            };
            let mut first_frame_new_mb = 0.0;
            for k in 0..2 {
                let frame = renderer.render(&scene, &photo, &params)?;
                if k == 0 {
                    first_frame_new_mb = frame.report.memory.new_bytes as f64 / 1e6;
                }
            }
            let mut memory = crate::gpu::pool::PoolStats::default();
            let mut times = Vec::with_capacity(frames as usize);
            let (mut timed_counters, mut pipelined_counters, mut live_counters) = (Vec::new(), Vec::new(), Vec::new());
            // per pass: its wall-clock times and its GPU times (where the adapter times them)
            let mut pass_times: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
            for _ in 0..frames {
                let start = Instant::now();
                let frame = renderer.render(&scene, &photo, &params)?;
                times.push(start.elapsed().as_secs_f64() * 1e3);
                memory = frame.report.memory;
                timed_counters.push(frame.report.counters);
                for (k, pass) in frame.report.passes.iter().enumerate() {
                    match pass_times.get_mut(k) {
                        Some((name, list, gpu)) if *name == pass.pass => {
                            list.push(pass.ms);
                            gpu.extend(pass.gpu_ms);
                        }
                        _ => {
                            pass_times.insert(k, (pass.pass.clone(), vec![pass.ms], pass.gpu_ms.into_iter().collect()))
                        }
                    }
                }
            }
            let passes: Vec<PassTime> = pass_times
                .into_iter()
                .map(|(pass, mut ms, mut gpu)| PassTime {
                    pass,
                    ms: quantile(&mut ms, 0.5),
                    // a median only where every timed frame had the pass's GPU time
                    gpu_ms: (gpu.len() == ms.len()).then(|| quantile(&mut gpu, 0.5)),
                })
                .collect();
            let median_ms = quantile(&mut times, 0.5);
            renderer.ctx.set_pass_waits(false);
            let mut pipelined = Vec::with_capacity(frames as usize);
            let mut live = Vec::with_capacity(frames as usize);
            let series = (|| {
                renderer.render(&scene, &photo, &params)?;
                for _ in 0..frames {
                    let start = Instant::now();
                    let frame = renderer.render(&scene, &photo, &params)?;
                    pipelined.push(start.elapsed().as_secs_f64() * 1e3);
                    pipelined_counters.push(frame.report.counters);
                }
                let mut state = crate::gpu::LiveState::default();
                renderer.render_display(&scene, &photo, &params, &mut state)?;
                for _ in 0..frames {
                    let start = Instant::now();
                    let frame = renderer.render_display(&scene, &photo, &params, &mut state)?;
                    live.push(start.elapsed().as_secs_f64() * 1e3);
                    live_counters.push(frame.report.counters);
                }
                Ok::<(), crate::error::RenderError>(())
            })();
            renderer.ctx.set_pass_waits(true);
            series?;
            let pipelined_median_ms = quantile(&mut pipelined, 0.5);
            let live_median_ms = quantile(&mut live, 0.5);
            let row = FrameRateRow {
                scene: name.clone(),
                condition,
                width,
                height,
                vpls: if condition == GiLevel::Gi { params.vpls } else { 0 },
                ism_size: if condition == GiLevel::Gi { params.ism_size } else { 0 },
                ism_points: if condition == GiLevel::Gi { params.ism_points } else { 0 },
                ism_splatting: (condition == GiLevel::Gi).then_some(ism_splatting),
                interleave: params.interleave,
                caustic_map_size: if specular && condition != GiLevel::None { 512 } else { 0 },
                frames,
                median_ms,
                p10_ms: quantile(&mut times, 0.1),
                p90_ms: quantile(&mut times, 0.9),
                fps: 1000.0 / median_ms.max(1e-9),
                pipelined_median_ms,
                pipelined_p10_ms: quantile(&mut pipelined, 0.1),
                pipelined_p90_ms: quantile(&mut pipelined, 0.9),
                pipelined_fps: 1000.0 / pipelined_median_ms.max(1e-9),
                live_median_ms,
                live_p10_ms: quantile(&mut live, 0.1),
                live_p90_ms: quantile(&mut live, 0.9),
                live_fps: 1000.0 / live_median_ms.max(1e-9),
                first_frame_new_mb,
                new_mb: memory.new_bytes as f64 / 1e6,
                reused_mb: memory.reused_bytes as f64 / 1e6,
                counters: summarise(&timed_counters),
                pipelined_counters: summarise(&pipelined_counters),
                live_counters: summarise(&live_counters),
                passes_ms: passes.iter().map(|p| p.ms).sum(),
                gpu_ms: passes.iter().any(|p| p.gpu_ms.is_some()).then(|| passes.iter().filter_map(|p| p.gpu_ms).sum()),
                passes,
            };
            let mut slowest: Vec<&PassTime> = row.passes.iter().collect();
            slowest.sort_by(|a, b| b.ms.total_cmp(&a.ms));
            let slowest: Vec<String> = slowest
                .iter()
                .take(3)
                .map(|p| match p.gpu_ms {
                    Some(gpu) => format!("{} {:.2} (GPU {gpu:.2})", p.pass, p.ms),
                    None => format!("{} {:.2}", p.pass, p.ms),
                })
                .collect();
            observer.line(&format!(
                "{:<14} {:<8} {:>9.2} {:>9.2} {:>9.2} {:>8.1} {:>12.2} {:>8.1} {:>8.2} {:>8.1} {}   {}",
                row.scene,
                match row.ism_splatting {
                    Some(IsmSplatting::Raster) => "gi/rast".to_string(),
                    _ => condition.name().to_string(),
                },
                row.median_ms,
                row.p10_ms,
                row.p90_ms,
                row.fps,
                row.pipelined_median_ms,
                row.pipelined_fps,
                row.live_median_ms,
                row.live_fps,
                row.live_counters.cells(),
                slowest.join("; ")
            ));
            rows.push(row);
        }
    }
    Ok(Report { adapter, rows, plots: Vec::new() })
}

/// The `q` quantile of `values` (nearest rank; sorts them); 0 for none.
fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let rank = ((q * values.len() as f64).ceil() as usize).clamp(1, values.len());
    values[rank - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_take_the_nearest_rank() {
        let mut v = vec![5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(quantile(&mut v, 0.5), 3.0);
        assert_eq!(quantile(&mut v, 0.1), 1.0);
        assert_eq!(quantile(&mut v, 0.9), 5.0);
        assert_eq!(quantile(&mut [], 0.5), 0.0);
    }
}
