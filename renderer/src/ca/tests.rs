//! Tests of the ca chain (CPU reference, and the GPU pass against it on the available adapter —
//! lavapipe on machines without a GPU; GPU tests print why and pass only when no adapter opens)
//! and of the estimators against images made by the simulated camera with known parameters.

use super::estimate;
use super::*;
use crate::gpu::ca::Artifacts;
use crate::gpu::context::GpuContext;
use crate::test_support::{assert_images_match, renderer_or_skip};

const W: u32 = 96;
const H: u32 = 72;

fn camera() -> Camera {
    Camera::from_fov(W, H, 50.0, Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y)
}

/// A textured "photograph" through the webcam, and a frame over it: a virtual disc (coverage 1)
/// with a colour ramp, a shadow (darker real pixels) and a brightened patch (indirect light).
fn frame() -> (Image, Image, Mask) {
    let cam = camera();
    let mut radiance = Image::new(W, H);
    for y in 0..H {
        for x in 0..W {
            let checker = if (x / 12 + y / 12) % 2 == 0 { 0.25 } else { 0.55 };
            radiance.set(x, y, Vec3::new(checker, checker * 0.9, checker * 0.7 + 0.05 * (x as f32 / W as f32)));
        }
    }
    let photo = sensor::apply(&radiance, &cam, &SensorParams::webcam());
    let mut composite = photo.clone();
    let mut mask = Mask::new(W, H);
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            let (dx, dy) = (x as f32 - 40.0, y as f32 - 34.0);
            if dx * dx + dy * dy < 15.0 * 15.0 {
                mask.values[i] = 1.0;
                composite.pixels[i] = Vec3::new(0.8 - dy * 0.01, 0.2 + dx * 0.01, 0.1);
            } else if (60..80).contains(&x) && (40..60).contains(&y) {
                composite.pixels[i] = photo.pixels[i] * 0.55; // a shadow
            } else if (8..24).contains(&x) && (50..66).contains(&y) {
                composite.pixels[i] = (photo.pixels[i] + Vec3::splat(0.12)).min(Vec3::ONE); // indirect light
            }
        }
    }
    (composite, photo, mask)
}

/// The shared GPU renderer's context and ca pass, or `None` after saying why the test skips.
fn gpu() -> Option<(&'static GpuContext, &'static Artifacts)> {
    renderer_or_skip().map(|renderer| (&renderer.ctx, &renderer.artifacts))
}

fn max_diff(a: &Image, b: &Image) -> f32 {
    a.pixels.iter().zip(&b.pixels).map(|(p, q)| (*p - *q).abs().max_element()).fold(0.0, f32::max)
}

#[test]
fn normal_deviates_have_unit_variance_and_depend_on_every_key() {
    let n = 200_000u32;
    let (mut s, mut s2) = (0.0f64, 0.0f64);
    for i in 0..n {
        let z = normal(7, i, i % 3) as f64;
        assert!(z.is_finite());
        s += z;
        s2 += z * z;
    }
    let mean = s / n as f64;
    let var = s2 / n as f64 - mean * mean;
    // standard errors: mean 1/√n ≈ 0.0022, variance √(2/n) ≈ 0.0032
    assert!(mean.abs() < 0.01, "mean {mean}");
    assert!((var - 1.0).abs() < 0.015, "variance {var}");
    assert_ne!(normal(7, 5, 0), normal(8, 5, 0));
    assert_ne!(normal(7, 5, 0), normal(7, 6, 0));
    assert_ne!(normal(7, 5, 0), normal(7, 5, 1));
}

#[test]
fn pcg_hash_matches_the_published_reference() {
    // pcg_hash(0..4) from Jarzynski & Olano's reference C code (JCGT 2020, "pcg"), values made by
    // renderer/tests/reference/pcg_hash.py
    let reference: [u32; 4] = [129708002, 2831084092, 2055130248, 2131687100];
    for (v, r) in reference.iter().enumerate() {
        assert_eq!(pcg_hash(v as u32), *r);
    }
}

#[test]
fn empty_mask_and_no_differential_leave_the_photograph_exactly() {
    let (_, photo, _) = frame();
    let mask = Mask::new(W, H);
    let p = CaParams::from_sensor(&SensorParams::webcam());
    let (out, report) = apply_cpu(&photo, &photo, &mask, &camera(), &p).unwrap();
    assert_eq!(out, photo);
    assert_eq!(report.processed_fraction, 0.0);
    if let Some((ctx, a)) = gpu() {
        let (out, report) = a.run(ctx, &photo, &photo, &mask, &camera(), &p).unwrap();
        assert_images_match("ca-gpu-without-virtual-objects", &out, &photo, 0.0, 0.0);
        assert_eq!(report.processed_fraction, 0.0);
    }
}

#[test]
fn cpu_and_gpu_agree_to_1e_3() {
    let Some((ctx, a)) = gpu() else { return };
    let (composite, photo, mask) = frame();
    // every stage but JPEG: all pixels within 1e-3
    let mut p = CaParams::from_sensor(&SensorParams::webcam());
    p.defocus_px = 1.3;
    p.jpeg_quality = None;
    let (cpu, _) = apply_cpu(&composite, &photo, &mask, &camera(), &p).unwrap();
    let (gpu, _) = a.run(ctx, &composite, &photo, &mask, &camera(), &p).unwrap();
    assert_images_match("ca-gpu-against-cpu", &gpu, &cpu, 1e-3, 0.0);
    assert!(max_diff(&cpu, &photo) > 0.05, "the chain changed nothing");
    // with the JPEG-style stage: a quantisation decision on a coefficient that lies on a
    // rounding boundary may flip between the two; all but 0.5 % of pixels within 1e-3
    p.jpeg_quality = Some(60);
    let (cpu, _) = apply_cpu(&composite, &photo, &mask, &camera(), &p).unwrap();
    let (gpu, _) = a.run(ctx, &composite, &photo, &mask, &camera(), &p).unwrap();
    assert_images_match("ca-gpu-against-cpu-jpeg", &gpu, &cpu, 1e-3, 0.005);
    let mean: f32 = cpu.pixels.iter().zip(&gpu.pixels).map(|(c, g)| (*c - *g).abs().max_element()).sum::<f32>()
        / cpu.pixels.len() as f32;
    assert!(mean < 1e-4, "mean |cpu − gpu| = {mean}");
}

#[test]
fn virtual_pixels_get_the_full_noise_and_differential_ones_only_what_is_missing() {
    // flat field, no other stage: variance in the virtual region = table; a brightened real
    // region gets var(P + D) − var(P); a shadow gets none
    let (w, h) = (128u32, 96u32);
    let cam = Camera::from_fov(w, h, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
    let photo = Image::filled(w, h, Vec3::splat(0.3));
    let mut composite = photo.clone();
    let mut mask = Mask::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if x < 42 {
                mask.values[i] = 1.0;
                composite.pixels[i] = Vec3::splat(0.6);
            } else if x < 84 {
                composite.pixels[i] = Vec3::splat(0.6); // brightened real surface
            } else {
                composite.pixels[i] = Vec3::splat(0.15); // shadow
            }
        }
    }
    let mut p = CaParams::off();
    p.seed = 3;
    for (k, v) in p.noise_variance.iter_mut().enumerate() {
        *v = 1e-4 + 2e-3 * k as f32 / 16.0;
    }
    let (out, _) = apply_cpu(&composite, &photo, &mask, &cam, &p).unwrap();
    let var = |x0: u32, x1: u32| {
        let vals: Vec<f64> = (0..h)
            .flat_map(|y| (x0..x1).map(move |x| (y, x)))
            .flat_map(|(y, x)| out.get(x, y).to_array())
            .map(|v| v as f64)
            .collect();
        let m = vals.iter().sum::<f64>() / vals.len() as f64;
        vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (vals.len() - 1) as f64
    };
    let lut = |d: f32| lut_variance(&p.noise_variance, d) as f64;
    // ~12 000 samples each: relative standard error of a variance ≈ 1.3 %
    let v_virtual = var(2, 40);
    assert!((v_virtual / lut(0.6) - 1.0).abs() < 0.06, "virtual {v_virtual} against {}", lut(0.6));
    let v_diff = var(44, 82);
    let expected = lut(0.6) - lut(0.3);
    assert!((v_diff / expected - 1.0).abs() < 0.06, "differential {v_diff} against {expected}");
    assert_eq!(var(86, 128), 0.0, "a shadow cannot remove noise, and adds none");
}

#[test]
fn nan_inputs_are_reported_not_propagated() {
    let (mut composite, mut photo, mask) = frame();
    composite.pixels[5] = Vec3::new(f32::NAN, 0.2, 0.2);
    composite.pixels[(35 * W + 40) as usize] = Vec3::splat(f32::INFINITY);
    photo.pixels[17] = Vec3::new(0.1, f32::NAN, 0.3);
    let p = CaParams::from_sensor(&SensorParams::webcam());
    let (out, report) = apply_cpu(&composite, &photo, &mask, &camera(), &p).unwrap();
    assert_eq!(report.invalid_inputs, 5);
    assert!(out.pixels.iter().all(|q| q.is_finite()));
    if let Some((ctx, a)) = gpu() {
        let (out, report) = a.run(ctx, &composite, &photo, &mask, &camera(), &p).unwrap();
        assert_eq!(report.invalid_inputs, 5);
        assert!(out.pixels.iter().all(|q| q.is_finite()));
    }
}

#[test]
fn hdr_inputs_above_one_give_finite_output_in_range() {
    let (mut composite, photo, mask) = frame();
    for (i, c) in composite.pixels.iter_mut().enumerate() {
        if mask.values[i] > 0.0 {
            *c *= 8.0; // HDR virtual radiance
        }
    }
    let p = CaParams::from_sensor(&SensorParams::webcam());
    let (out, _) = apply_cpu(&composite, &photo, &mask, &camera(), &p).unwrap();
    assert!(out.pixels.iter().all(|q| q.is_finite() && q.min_element() >= 0.0 && q.max_element() <= 1.0));
}

#[test]
fn bad_parameters_and_sizes_are_refused_with_a_sentence() {
    let (composite, photo, mask) = frame();
    let mut p = CaParams::off();
    p.defocus_px = f32::NAN;
    let e = apply_cpu(&composite, &photo, &mask, &camera(), &p).unwrap_err().to_string();
    assert!(e.contains("defocus"), "{e}");
    let small = Image::new(4, 4);
    assert!(matches!(
        apply_cpu(&composite, &small, &mask, &camera(), &CaParams::off()),
        Err(RenderError::SizeMismatch { .. })
    ));
}

#[test]
fn scene_noise_table_is_the_response_of_the_clipped_noisy_sensor_value() {
    // linear response, away from the clip: σ²(d) = a·d + b exactly
    let mut s = SensorParams::clean();
    s.response = ToneCurve::Linear;
    s.noise = [0.01, 0.001];
    let lut = display_noise_lut(&s);
    for (k, v) in lut.iter().enumerate().take(11).skip(6) {
        let d = k as f32 / 16.0;
        assert!((v / (0.01 * d + 0.001) - 1.0).abs() < 2e-3, "{k}: {v}");
    }
    // sRGB and the webcam (Filmic, contrast 1.1): Monte Carlo with numpy, 10^7 draws per entry,
    // renderer/tests/reference/ca_noise_lut.py
    s.response = ToneCurve::Srgb;
    let srgb = display_noise_lut(&s);
    let web = display_noise_lut(&SensorParams::webcam());
    for (k, reference_srgb, reference_web) in [
        (0usize, 0.0088437f32, 0.0029812f32),
        (2, 0.011602, 0.0060338),
        (8, 0.0040345, 0.001015),
        (14, 0.0023399, 6.69e-05),
    ] {
        assert!((srgb[k] / reference_srgb - 1.0).abs() < 0.01, "sRGB {k}: {} against {reference_srgb}", srgb[k]);
        assert!((web[k] / reference_web - 1.0).abs() < 0.01, "webcam {k}: {} against {reference_web}", web[k]);
    }
}

// ---------------------------------------------------------------- estimators

/// A smooth ramp (left to right 0.1 … 0.9 in linear sensor values) with a few rectangles.
fn test_scene(w: u32, h: u32) -> Image {
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut v = 0.1 + 0.8 * x as f32 / w as f32;
            if (x / 24 + y / 24) % 3 == 0 {
                v = 0.5 * v + 0.35;
            }
            img.set(x, y, Vec3::splat(v));
        }
    }
    img
}

#[test]
fn noise_estimator_recovers_a_and_b_of_the_simulated_camera() {
    let (w, h) = (256u32, 192u32);
    let cam = Camera::from_fov(w, h, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
    let mut s = SensorParams::clean();
    s.response = ToneCurve::Linear;
    s.noise = [0.004, 0.0002];
    let img = sensor::apply(&test_scene(w, h), &cam, &s);
    let est = estimate::noise(&img, None);
    assert_eq!(est.fit, "poisson-gaussian");
    // truth at d: a·d + b + 1/12 LSB² of quantisation; within 12 % at d = 0.25 and 0.75
    for d in [0.25f32, 0.75] {
        let truth = 0.004 * d + 0.0002 + (1.0f32 / 255.0).powi(2) / 12.0;
        let fitted = est.a * d + est.b;
        assert!((fitted / truth - 1.0).abs() < 0.12, "d {d}: fitted {fitted} truth {truth} ({est:?})");
    }
}

#[test]
fn noise_estimator_on_uniform_saturated_hdr_and_nan_images() {
    // uniform and noiseless: σ = 0, no NaN
    let flat = Image::filled(64, 48, Vec3::splat(0.4));
    let est = estimate::noise(&flat, None);
    assert_eq!((est.sigma, est.a, est.b), (0.0, 0.0, 0.0));
    // fully saturated (or HDR above 1): no usable sample → the documented fallback
    for v in [1.0f32, 3.5] {
        let est = estimate::noise(&Image::filled(64, 48, Vec3::splat(v)), None);
        assert_eq!(est.fit, "none");
        assert_eq!((est.a, est.b), (0.0, 0.0));
    }
    // half the image clipped at 1: the other half's noise is still found
    let (w, h) = (128u32, 96u32);
    let cam = Camera::from_fov(w, h, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
    let mut s = SensorParams::clean();
    s.response = ToneCurve::Linear;
    s.noise = [0.0, 0.0004];
    let mut radiance = Image::filled(w, h, Vec3::splat(0.5));
    for y in 0..h {
        for x in 0..w / 2 {
            radiance.set(x, y, Vec3::splat(4.0));
        }
    }
    let mut img = sensor::apply(&radiance, &cam, &s);
    img.pixels[300] = Vec3::splat(f32::NAN);
    let est = estimate::noise(&img, None);
    assert!(est.sigma.is_finite() && est.a.is_finite() && est.b.is_finite());
    assert!((est.sigma / 0.0004f32.sqrt() - 1.0).abs() < 0.1, "{est:?}");
}

#[test]
fn blur_estimator_recovers_the_defocus_radius() {
    let (w, h) = (160u32, 120u32);
    let cam = Camera::from_fov(w, h, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
    // a disc and a tilted square: edges at all angles, area-sampled (4×4)
    let mut radiance = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = x as f32 + (sx as f32 + 0.5) / 4.0;
                    let py = y as f32 + (sy as f32 + 0.5) / 4.0;
                    let disc = (px - 50.0).powi(2) + (py - 60.0).powi(2) < 30.0 * 30.0;
                    let (u, v) = ((px - 118.0) * 0.94 + (py - 60.0) * 0.34, -(px - 118.0) * 0.34 + (py - 60.0) * 0.94);
                    if disc || (u.abs() < 22.0 && v.abs() < 22.0) {
                        s += 1.0;
                    }
                }
            }
            radiance.set(x, y, Vec3::splat(0.15 + 0.5 * s / 16.0));
        }
    }
    for (radius, noise) in [(0.0f32, 0.0f32), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (2.0, 0.0002)] {
        let mut s = SensorParams::clean();
        s.response = ToneCurve::Linear;
        s.defocus_px = radius;
        s.noise = [0.0, noise];
        let img = sensor::apply(&radiance, &cam, &s);
        let est = estimate::blur(&img, None);
        let r = est.radius_px.unwrap_or_else(|| panic!("no edge found at radius {radius}"));
        assert!((r - radius).abs() <= 0.4, "radius {radius} (noise {noise}): estimated {r} from {} edges", est.edges);
    }
    // no edges: None, no NaN
    let est = estimate::blur(&Image::filled(64, 48, Vec3::splat(0.3)), None);
    assert_eq!(est.radius_px, None);
}

#[test]
fn jpeg_estimator_recovers_the_quality() {
    let (w, h) = (128u32, 96u32);
    let cam = Camera::from_fov(w, h, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
    // texture with energy at low frequencies in every block
    let mut radiance = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let v = 0.3
                + 0.15 * ((x as f32 * 0.37).sin() + (y as f32 * 0.23).cos())
                + 0.1 * (((x * 7 + y * 13) % 17) as f32 / 17.0);
            radiance.set(x, y, Vec3::new(v, v * 0.8, v * 0.6));
        }
    }
    let mut s = SensorParams::clean();
    s.noise = [0.0, 0.00005];
    for quality in [30u8, 50, 75, 90] {
        s.jpeg_quality = Some(quality);
        let img = sensor::apply(&radiance, &cam, &s);
        let est = estimate::jpeg_quality(&img);
        let q = est.quality.unwrap_or_else(|| panic!("quality {quality} not detected: {:?}", est.steps));
        assert!((q as i32 - quality as i32).abs() <= 5, "quality {quality}: estimated {q} ({:?})", est.steps);
    }
    s.jpeg_quality = None;
    let est = estimate::jpeg_quality(&sensor::apply(&radiance, &cam, &s));
    assert_eq!(est.quality, None, "{:?}", est.steps);
}

/// The camera's own image of a scene, and the same image with every artifact stage off (what a
/// renderer makes): the ca chain on the latter should show the former's noise and blur.
fn camera_and_clean(preset: &str) -> (Image, Image, SensorParams, Camera) {
    let (w, h) = (192u32, 144u32);
    let cam = Camera::from_fov(w, h, 50.0, Vec3::Z, Vec3::ZERO, Vec3::Y);
    let mut radiance = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = x as f32 + (sx as f32 + 0.5) / 4.0;
                    let py = y as f32 + (sy as f32 + 0.5) / 4.0;
                    let disc = (px - 60.0).powi(2) + (py - 70.0).powi(2) < 34.0 * 34.0;
                    let square = (px - 140.0).abs() < 28.0 && (py - 72.0).abs() < 28.0;
                    s += if disc {
                        1.0
                    } else if square {
                        0.5
                    } else {
                        0.0
                    };
                }
            }
            let shade = 0.1 + 0.3 * x as f32 / w as f32 + 0.1 * y as f32 / h as f32;
            radiance.set(
                x,
                y,
                Vec3::new(shade + 0.35 * s / 16.0, shade * 0.9 + 0.3 * s / 16.0, shade * 0.8 + 0.2 * s / 16.0),
            );
        }
    }
    let s = SensorParams::preset(preset).unwrap();
    let mut clean = s.clone();
    clean.distortion = [0.0; 5];
    clean.chromatic_aberration = 0.0;
    clean.defocus_px = 0.0;
    clean.bayer = false;
    clean.noise = [0.0, 0.0];
    clean.sharpen = 0.0;
    clean.jpeg_quality = None;
    clean.vignetting = 0.0;
    let mut ideal = s.clone();
    ideal.distortion = [0.0; 5];
    ideal.chromatic_aberration = 0.0;
    ideal.vignetting = 0.0;
    (sensor::apply(&radiance, &cam, &ideal), sensor::apply(&radiance, &cam, &clean), s, cam)
}

#[test]
fn the_chain_on_a_clean_image_reproduces_the_cameras_noise_and_blur() {
    // the simulated camera's own image against the same image with its artifact stages off and
    // the ca chain applied instead (scene parameters, and parameters estimated from the former);
    // both measured by the estimators, on 8-bit values
    // (distortion is off in both: the estimators compare statistics, not registration)
    for preset in ["webcam", "phone"] {
        let (photo, clean, s, cam) = camera_and_clean(preset);
        let all = Mask { width: clean.width, height: clean.height, values: vec![1.0; clean.pixels.len()] };
        let target_noise = estimate::noise(&photo, None).sigma;
        let target_blur = estimate::blur(&photo, None).radius_px.unwrap();
        let mut scene_p = CaParams::from_sensor(&s);
        scene_p.distortion = [0.0; 5];
        scene_p.chromatic_aberration = 0.0;
        let (est_p, _) = estimate::params_from_photo(&photo, &s);
        let mut est_p = est_p;
        est_p.distortion = [0.0; 5];
        est_p.chromatic_aberration = 0.0;
        for (name, p) in [("scene", &scene_p), ("estimate", &est_p)] {
            let (out, _) = apply_cpu(&clean, &clean, &all, &cam, p).unwrap();
            let out = estimate::quantised(&out);
            let n = estimate::noise(&out, None).sigma;
            let b = estimate::blur(&out, None).radius_px.unwrap();
            eprintln!(
                "{preset} {name}: noise {n:.5} (camera {target_noise:.5}), blur {b:.2} (camera {target_blur:.2}); params defocus {:.2} noise(0.5) {:.2e} jpeg {:?}",
                p.defocus_px,
                lut_variance(&p.noise_variance, 0.5),
                p.jpeg_quality
            );
            // measured when written: webcam scene 0.00203/0.00208, estimate 0.00180; phone scene
            // 0.00273/0.00334 (saturation, which amplifies chroma noise, is not simulated),
            // estimate 0.00364; blur within 0.12 px
            assert!(
                (n / target_noise - 1.0).abs() < 0.25,
                "{preset} {name}: noise {n} against the camera's {target_noise}"
            );
            assert!((b - target_blur).abs() < 0.3, "{preset} {name}: blur {b} against the camera's {target_blur}");
        }
    }
}

#[test]
fn parameters_from_a_uniform_photograph_fall_back_without_nan() {
    // nothing to measure: no noise, no edges, no JPEG steps → noise 0, defocus 0, no JPEG stage;
    // the scene's optics stay
    for v in [0.0f32, 0.5, 1.0, 7.0] {
        let photo = Image::filled(64, 48, Vec3::splat(v));
        let (p, est) = estimate::params_from_photo(&photo, &SensorParams::webcam());
        assert_eq!(p.source, ParamSource::Estimate);
        assert!(p.noise_variance.iter().all(|x| *x == 0.0), "{v}: {:?}", p.noise_variance);
        assert_eq!(p.defocus_px, 0.0);
        assert_eq!(p.jpeg_quality, None);
        assert_eq!(est.blur.radius_px, None);
        assert!(p.check().is_ok());
        assert_eq!(p.distortion, SensorParams::webcam().distortion);
    }
}

#[test]
fn cpu_and_gpu_agree_at_an_odd_size_with_every_stage() {
    // 61×43: partial 8×8 blocks, odd Bayer borders, clamped taps at every edge
    let Some((ctx, a)) = gpu() else { return };
    let (composite, photo, mask) = frame();
    let (w, h) = (61u32, 43u32);
    let composite = composite.resized(w, h);
    let photo = photo.resized(w, h);
    let m = Mask { width: W, height: H, values: mask.values.clone() }.to_image().resized(w, h);
    let mask = Mask { width: w, height: h, values: m.pixels.iter().map(|p| p.x).collect() };
    let cam = Camera::from_fov(w, h, 50.0, Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y);
    let mut p = CaParams::from_sensor(&SensorParams::webcam());
    p.defocus_px = 2.2;
    p.chromatic_aberration = 0.01;
    p.jpeg_quality = None;
    let (cpu, _) = apply_cpu(&composite, &photo, &mask, &cam, &p).unwrap();
    let (gpu, _) = a.run(ctx, &composite, &photo, &mask, &cam, &p).unwrap();
    assert_images_match("ca-gpu-against-cpu-odd-size", &gpu, &cpu, 1e-3, 0.0);
    p.jpeg_quality = Some(35);
    let (cpu, _) = apply_cpu(&composite, &photo, &mask, &cam, &p).unwrap();
    let (gpu, _) = a.run(ctx, &composite, &photo, &mask, &cam, &p).unwrap();
    assert_images_match("ca-gpu-against-cpu-odd-size-jpeg", &gpu, &cpu, 1e-3, 0.005);
}
