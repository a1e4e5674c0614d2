//! Tests of the CPU colour mapping on synthetic buffers: known transforms recovered, and the
//! hard cases (uniform proxy, empty mask, too few pairs, singular systems, saturated camera
//! pixels, HDR input) with their documented fallbacks and no NaN; and the statistics mapping on
//! a subsample of a real render against an independent computation (colour-science).

use super::colour::*;
use super::*;
use crate::math::Rng;
use crate::surface;
use glam::Mat3;

/// A frame of 8×8 patches of random colours on real surfaces (L_r up to `peak`), a virtual
/// block in the middle, the camera made by `camera` from L_r.
pub(crate) struct Frame {
    pub width: u32,
    pub height: u32,
    pub l_rv: Vec<Vec3>,
    pub l_r: Vec<Vec3>,
    pub flags: Vec<u32>,
    pub photo: Vec<Vec3>,
}

impl Frame {
    pub fn new(width: u32, height: u32, peak: f32, seed: u64, camera: impl Fn(Vec3) -> Vec3) -> Frame {
        let n = (width * height) as usize;
        let (mut l_rv, mut l_r, mut flags, mut photo) =
            (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
        for y in 0..height {
            for x in 0..width {
                let mut rng = Rng::for_stream(seed, ((y / 8) * 1000 + x / 8) as u64, 0);
                let c =
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * peak * 0.9 + Vec3::splat(0.05 * peak);
                let virt = x >= width / 3 && x < 2 * width / 3 && y >= height / 3 && y < 2 * height / 3;
                // the virtual object is a red-ish shaded block; L_rv on real pixels adds a shadow
                let shade = 0.3 + 0.7 * (x as f32 / width as f32);
                if virt {
                    l_rv.push(Vec3::new(0.8, 0.25, 0.1) * peak * shade);
                    l_r.push(Vec3::ZERO);
                    flags.push(2);
                } else {
                    let darken = if y > 2 * height / 3 && x > width / 3 { 0.5 } else { 1.0 };
                    l_rv.push(c * darken);
                    l_r.push(c);
                    flags.push(1);
                }
                photo.push(camera(c));
            }
        }
        Frame { width, height, l_rv, l_r, flags, photo }
    }
    pub fn input(&self) -> CmInput<'_> {
        CmInput {
            width: self.width,
            height: self.height,
            l_rv: &self.l_rv,
            l_r: &self.l_r,
            flags: &self.flags,
            photo: &self.photo,
        }
    }
}

fn params(method: CmMethod) -> CmParams {
    CmParams { method, ..CmParams::default() }
}

fn all_finite(out: &CmOutput) {
    for v in out.mapped_rv.iter().chain(&out.mapped_r).chain(&out.composite) {
        assert!(v.is_finite(), "non-finite value {v} ({:?})", out.report);
    }
    for v in &out.composite {
        assert!(v.min_element() >= 0.0 && v.max_element() <= 1.0, "composite {v} outside [0, 1]");
    }
}

#[test]
fn off_is_reinhard_then_srgb_and_composes_like_the_old_shader() {
    let f = Frame::new(48, 36, 1.0, 1, |c| srgb_encode3(tone_map(c, 1.0)));
    let out = cpu_frame(&f.input(), &params(CmMethod::Off), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    let x = Vec3::new(0.5, 2.0, 0.0);
    assert_eq!(Mapping::Off.apply(x, 1.0), Vec3::new(srgb_encode(1.0 / 3.0), srgb_encode(2.0 / 3.0), 0.0));
    // virtual pixels show τ(L_rv), real ones photo + τ(L_rv) − τ(L_r)
    let i = (18 * 48 + 24) as usize;
    assert_eq!(out.composite[i], srgb_encode3(tone_map(f.l_rv[i], 1.0)).clamp(Vec3::ZERO, Vec3::ONE));
}

#[test]
fn without_a_differential_every_method_returns_the_photograph_bit_for_bit() {
    let mut f = Frame::new(48, 36, 3.0, 2, |c| gamma_encode(c * 0.3));
    f.flags.iter_mut().for_each(|g| *g = 1);
    f.l_r = f.l_r.iter().map(|c| if *c == Vec3::ZERO { Vec3::splat(0.5) } else { *c }).collect();
    f.l_rv = f.l_r.clone();
    for method in CmMethod::ALL {
        for composition in [Composition::Additive, Composition::Scaled] {
            let out = cpu_frame(&f.input(), &params(method), 1.0, composition, &mut CmState::default());
            assert_eq!(out.composite, f.photo, "{method:?} {composition:?}");
        }
    }
}

#[test]
fn statistics_transfers_a_known_lab_shift_and_scale() {
    // camera = the Lab transfer of TM(L_r) with known ratio and means: the estimate recovers it
    let (ratio, shift) = (Vec3::new(1.2, 0.8, 1.1), Vec3::new(-3.0, 4.0, -6.0));
    let f0 = Frame::new(64, 48, 1.0, 3, |c| c);
    let labs: Vec<Vec3> =
        f0.l_r.iter().zip(&f0.flags).filter(|(_, g)| **g == 1).map(|(c, _)| linear_to_lab(tone_map(*c, 1.0))).collect();
    let mean = labs.iter().copied().sum::<Vec3>() / labs.len() as f32;
    let f = Frame::new(64, 48, 1.0, 3, |c| {
        let lab = (linear_to_lab(tone_map(c, 1.0)) - mean) * ratio + mean + shift;
        srgb_encode3(lab_to_linear(lab).max(Vec3::ZERO))
    });
    let out = cpu_frame(&f.input(), &params(CmMethod::Statistics), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    let Mapping::Statistics { mean_source, mean_target, ratio: r } = out.report.mapping else {
        panic!("{:?}", out.report)
    };
    for c in 0..3 {
        assert!((r[c] - ratio[c]).abs() < 0.03, "ratio {r:?} against {ratio}");
        assert!((mean_target[c] - mean_source[c] - shift[c]).abs() < 0.3, "means {mean_source:?} {mean_target:?}");
    }
    assert!(out.report.fallback.is_none());
    assert!(out.report.warning.is_none(), "ratios 1.2, 0.8, 1.1 warned: {:?}", out.report.warning);
}

/// The sums of [`statistics::contribution`] over `n` pixels whose Lab channels have the given
/// (mean, σ) in TM(L_r) and in the camera.
fn sums_of(n: f64, source: [(f64, f64); 3], target: [(f64, f64); 3]) -> [f64; statistics::K] {
    let mut sums = [0.0; statistics::K];
    sums[0] = n;
    for c in 0..3 {
        let ((ms, ss), (mt, st)) = (source[c], target[c]);
        sums[1 + c] = n * ms;
        sums[4 + c] = n * (ss * ss + ms * ms);
        sums[7 + c] = n * mt;
        sums[10 + c] = n * (st * st + mt * mt);
    }
    sums
}

#[test]
fn statistics_warns_of_ratios_outside_half_to_two_as_on_dir_lamp_box_and_not_on_the_survey_scenes() {
    // docs/renderer.md's measurement of dir-lamp-box (cm, 256×192): ratios L 1.03, a 19.9, b 8.65
    let grey =
        sums_of(29506.0, [(53.09, 9.76), (0.37, 0.146), (0.93, 0.391)], [(58.54, 10.05), (0.55, 2.91), (5.07, 3.38)]);
    let warning = statistics::ratio_warning(&grey).expect("dir-lamp-box's ratios warn");
    let named: Vec<&str> = warning.channels.iter().map(|c| c.channel).collect();
    assert_eq!(named, ["a", "b"], "{warning:?}");
    let Mapping::Statistics { ratio, .. } = statistics::solve(&grey).0 else { panic!("no statistics mapping") };
    assert_eq!(
        [warning.channels[0].ratio, warning.channels[1].ratio],
        [ratio[1], ratio[2]],
        "the warning's ratios are the mapping's"
    );
    assert!(
        (warning.channels[0].sd_camera - 2.91).abs() < 1e-4 && (warning.channels[0].sd_render - 0.146).abs() < 1e-4
    );
    let sentence = warning.sentence("dir-lamp-box");
    for part in [
        "scene \"dir-lamp-box\"",
        "a 19.9 (σ camera 2.91 / σ render 0.146)",
        "b 8.64 (σ camera 3.38 / σ render 0.391)",
        "chroma multiplied about 19.9× (colours may clip)",
        "docs/renderer.md, \"The statistics mapping on a grey real scene",
    ] {
        assert!(sentence.contains(part), "{part:?} missing from: {sentence}");
    }
    assert!(!sentence.contains("lightness") && !sentence.contains("NaN") && !sentence.contains("inf"), "{sentence}");
    // the survey scenes' ratios (L 0.80–0.89, a 0.83–1.41, b 0.80–0.89): no warning
    let survey = sums_of(20000.0, [(55.0, 12.0), (4.0, 4.0), (12.0, 6.0)], [(50.0, 9.6), (5.0, 5.64), (10.0, 4.8)]);
    assert!(statistics::ratio_warning(&survey).is_none(), "{:?}", statistics::ratio_warning(&survey));
    // just outside on either side; a lightness ratio below 0.5 washes out
    let edges = sums_of(100.0, [(50.0, 10.0), (0.0, 4.0), (0.0, 4.0)], [(50.0, 4.9), (0.0, 8.0), (0.0, 8.1)]);
    let warning = statistics::ratio_warning(&edges).expect("0.49 and 2.025 warn");
    let named: Vec<&str> = warning.channels.iter().map(|c| c.channel).collect();
    assert_eq!(named, ["L", "b"], "{warning:?}");
    assert!(
        warning.message.contains("lightness contrast multiplied about 0.490× (colours may wash out)"),
        "{}",
        warning.message
    );
    // a flat channel (the uniform-proxy fallback, ratio 1) and an empty mask: no warning
    let flat = sums_of(100.0, [(50.0, 10.0), (1.0, 0.0), (1.0, 0.0)], [(50.0, 10.0), (0.0, 3.0), (0.0, 3.0)]);
    assert!(statistics::ratio_warning(&flat).is_none());
    assert!(statistics::ratio_warning(&[0.0; statistics::K]).is_none());
}

#[test]
fn a_uniform_proxy_has_zero_variance_and_falls_back_to_a_mean_shift() {
    let mut f = Frame::new(48, 36, 1.0, 4, |c| srgb_encode3(c * 0.7));
    for (c, g) in f.l_r.iter_mut().zip(&f.flags) {
        if *g == 1 {
            *c = Vec3::new(0.4, 0.3, 0.2);
        }
    }
    let out = cpu_frame(&f.input(), &params(CmMethod::Statistics), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    let Mapping::Statistics { ratio, .. } = out.report.mapping else { panic!() };
    assert_eq!(ratio, [1.0; 3]);
    assert!(out.report.fallback.as_deref().unwrap().contains("zero variance"), "{:?}", out.report.fallback);
    // zero variance in the camera instead: ratio 0, still finite
    let mut g = Frame::new(48, 36, 1.0, 4, |_| Vec3::splat(0.5));
    g.photo.iter_mut().for_each(|p| *p = Vec3::splat(0.5));
    let out = cpu_frame(&g.input(), &params(CmMethod::Statistics), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    let Mapping::Statistics { ratio, .. } = out.report.mapping else { panic!() };
    assert!(ratio.iter().all(|r| r.abs() < 1e-2), "{ratio:?}");
}

#[test]
fn a_mask_that_empties_the_image_falls_back_for_every_method() {
    // every pixel virtual: n = n_zero
    let mut f = Frame::new(32, 24, 1.0, 5, srgb_encode3);
    f.flags.iter_mut().for_each(|g| *g = 2);
    f.l_r.iter_mut().for_each(|c| *c = Vec3::ZERO);
    for method in [CmMethod::Statistics, CmMethod::Samples, CmMethod::Rohmer] {
        let out = cpu_frame(&f.input(), &params(method), 1.0, Composition::Scaled, &mut CmState::default());
        all_finite(&out);
        assert!(out.report.fallback.is_some(), "{method:?} reported no fallback");
        assert_eq!(out.report.pairs, 0, "{method:?}");
    }
}

#[test]
fn saturated_camera_pixels_are_excluded() {
    // the brightest patches clip in the camera: statistics count them out, Rohmer still
    // recovers the exposure gain of the rest
    let gain = 0.6;
    let f = Frame::new(64, 48, 2.5, 6, |c| gamma_encode(c * gain));
    let input = f.input();
    let p = params(CmMethod::Statistics);
    let clipped =
        (0..f.photo.len()).filter(|&i| f.flags[i] == surface::REAL && f.photo[i].max_element() >= p.saturated).count();
    assert!(clipped > 100, "test needs clipped pixels ({clipped})");
    let sums = statistics::cpu_sums(&input, &p, 1.0);
    let real = f.flags.iter().filter(|g| **g == 1).count();
    assert_eq!(sums[0] as usize, real - clipped);
    let out = cpu_frame(&input, &params(CmMethod::Rohmer), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    let Mapping::Linear { rows } = out.report.mapping else { panic!() };
    for (k, row) in rows.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            let want = if j == k { gain } else { 0.0 };
            assert!((v - want).abs() < 0.02, "C⁻¹ {rows:?} against {gain}·I ({:?})", out.report.fallback);
        }
    }
}

#[test]
fn rohmer_recovers_a_colour_matrix_and_its_inverse_maps_back() {
    // u = M r (white balance with some cross-talk), camera = u^(1/2.2): C = M⁻¹, mapping = M
    let m = Mat3::from_cols_array_2d(&[[0.55, 0.03, 0.02], [0.05, 0.5, 0.04], [0.01, 0.05, 0.42]]);
    let f = Frame::new(96, 72, 1.2, 7, |c| gamma_encode(m * c));
    let out = cpu_frame(&f.input(), &params(CmMethod::Rohmer), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    assert!(out.report.fallback.is_none(), "{:?}", out.report.fallback);
    assert!(out.report.pairs > 1000, "{} pairs", out.report.pairs);
    let Mapping::Linear { rows } = out.report.mapping else { panic!() };
    let got = rohmer::from_rows(rows);
    for (a, b) in got.to_cols_array().iter().zip(m.to_cols_array()) {
        assert!((a - b).abs() < 0.01, "C⁻¹ = {got} against {m}");
    }
}

#[test]
fn rohmer_falls_back_to_the_diagonal_approximation_for_grey_only_pairs() {
    // all real colours grey: U W² Uᵀ has rank 1; A_t still recovers the per-channel gains
    let gains = Vec3::new(0.5, 0.45, 0.4);
    let mut f = Frame::new(64, 48, 1.0, 8, |c| c);
    for (i, c) in f.l_r.iter_mut().enumerate() {
        if f.flags[i] == surface::REAL {
            *c = Vec3::splat(c.x);
        }
    }
    f.photo = f.l_r.iter().map(|c| gamma_encode(*c * gains)).collect();
    let out = cpu_frame(&f.input(), &params(CmMethod::Rohmer), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    assert!(out.report.fallback.as_deref().unwrap().contains("ill-conditioned"), "{:?}", out.report.fallback);
    let Mapping::Linear { rows } = out.report.mapping else { panic!() };
    for k in 0..3 {
        assert!((rows[k][k] - gains[k]).abs() < 0.01, "{rows:?}");
    }
    // an explicitly singular system through fit_matrix, and too few pairs
    let p = CmParams::default();
    let a = Mat3::from_diagonal(Vec3::splat(2.0));
    let mut sums = vec![0f64; rohmer::KF];
    sums[0] = 5000.0;
    let (c, why) = rohmer::fit_matrix(&sums, &a, &p);
    assert_eq!(c, a);
    assert!(why.unwrap().contains("singular"));
    sums[0] = 5.0;
    assert!(rohmer::fit_matrix(&sums, &a, &p).1.unwrap().contains("fewer than"));
}

#[test]
fn samples_fit_a_known_affine_camera_and_smooth_across_frames() {
    // camera = A·sRGB(TM(L_r)) + b: the affine regression recovers it from matched pairs
    let a = [[0.9, 0.05, 0.0, 0.03], [0.02, 0.8, 0.05, 0.05], [0.0, 0.1, 0.7, 0.02]];
    let affine = |c: Vec3, a: [[f32; 4]; 3]| {
        let d = srgb_encode3(tone_map(c, 1.0));
        Vec3::new(
            a[0][0] * d.x + a[0][1] * d.y + a[0][2] * d.z + a[0][3],
            a[1][0] * d.x + a[1][1] * d.y + a[1][2] * d.z + a[1][3],
            a[2][0] * d.x + a[2][1] * d.y + a[2][2] * d.z + a[2][3],
        )
    };
    let f = Frame::new(64, 48, 1.0, 9, |c| affine(c, a));
    let mut state = CmState::default();
    let out = cpu_frame(&f.input(), &params(CmMethod::Samples), 1.0, Composition::Additive, &mut state);
    all_finite(&out);
    let Mapping::Affine { rows } = out.report.mapping else { panic!() };
    // the swapped pairs distort the fit only where the camera is not channel-symmetric; the
    // pairs themselves lie on the true map, so check the map on the sampled colours
    let pairs = out.report.pairs;
    assert!(pairs >= 8, "{pairs}");
    assert!(rows.iter().flatten().all(|v| v.is_finite()));
    // smoothing: a second frame with another camera gives u·new + (1 − u)·old exactly
    let first = rows;
    let b = [[0.5, 0.0, 0.0, 0.1], [0.0, 0.5, 0.0, 0.1], [0.0, 0.0, 0.5, 0.1]];
    let g = Frame::new(64, 48, 1.0, 9, |c| affine(c, b));
    let fresh = cpu_frame(&g.input(), &params(CmMethod::Samples), 1.0, Composition::Additive, &mut CmState::default());
    let Mapping::Affine { rows: new } = fresh.report.mapping else { panic!() };
    let second = cpu_frame(&g.input(), &params(CmMethod::Samples), 1.0, Composition::Additive, &mut state);
    let Mapping::Affine { rows: smoothed } = second.report.mapping else { panic!() };
    for k in 0..3 {
        for j in 0..4 {
            assert!((smoothed[k][j] - (0.3 * new[k][j] + 0.7 * first[k][j])).abs() < 1e-6);
        }
    }
    assert_eq!(state.frames, 2);
    // a channel-symmetric camera (same affine on every channel) is recovered exactly
    let c = [[0.8, 0.0, 0.0, 0.05], [0.0, 0.8, 0.0, 0.05], [0.0, 0.0, 0.8, 0.05]];
    let mut h = Frame::new(64, 48, 1.0, 9, |x| affine(x, c));
    // virtual objects of many hues, so that the matched pairs span the colour space
    for i in 0..h.l_rv.len() {
        if h.flags[i] == surface::VIRTUAL {
            let mut rng = Rng::for_stream(99, i as u64 / 5, 0);
            h.l_rv[i] = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        }
    }
    let out = cpu_frame(&h.input(), &params(CmMethod::Samples), 1.0, Composition::Additive, &mut CmState::default());
    let Mapping::Affine { rows } = out.report.mapping else { panic!() };
    assert!(out.report.fallback.is_none(), "{:?}", out.report.fallback);
    for k in 0..3 {
        for j in 0..4 {
            assert!((rows[k][j] - c[k][j]).abs() < 1e-3, "{rows:?}");
        }
    }
}

#[test]
fn samples_with_fewer_pairs_than_unknowns_fall_back() {
    let pairs = vec![(Vec3::new(0.2, 0.3, 0.4), Vec3::new(0.25, 0.3, 0.35))];
    assert!(samples::regress(&pairs, Regression::Affine).is_none());
    let (rows, why) = samples::fit(&pairs, Regression::Affine);
    assert_eq!(rows, samples::IDENTITY);
    assert!(why.unwrap().contains("too few or singular"));
    // two pairs of distinct values: the per-channel polynomial fits, the affine one cannot
    let pairs = vec![(Vec3::splat(0.2), Vec3::splat(0.3)), (Vec3::splat(0.6), Vec3::splat(0.5))];
    let (rows, why) = samples::fit(&pairs, Regression::Affine);
    assert!(why.unwrap().contains("per-channel"));
    assert!((rows[0][0] - 0.5).abs() < 1e-5 && (rows[0][3] - 0.2).abs() < 1e-5, "{rows:?}");
    // one virtual pixel in a frame: one pair plus its swap, below the affine's four unknowns
    let mut f = Frame::new(32, 24, 1.0, 10, srgb_encode3);
    let first_virtual = f.flags.iter().position(|g| *g == 2).unwrap();
    for (i, g) in f.flags.iter_mut().enumerate() {
        if *g == 2 && i != first_virtual {
            *g = 1;
        }
    }
    let out = cpu_frame(&f.input(), &params(CmMethod::Samples), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    assert_eq!(out.report.pairs, 2);
    assert!(out.report.fallback.is_some());
}

#[test]
fn hdr_inputs_above_one_stay_finite_in_every_method_and_composition() {
    let f = Frame::new(48, 36, 50.0, 11, |c| srgb_encode3(tone_map(c, 0.2)));
    for method in CmMethod::ALL {
        for composition in [Composition::Additive, Composition::Scaled] {
            let out = cpu_frame(&f.input(), &params(method), 1.0, composition, &mut CmState::default());
            all_finite(&out);
        }
    }
    // NaN in the inputs: the mapping of a NaN pixel is not defined, but the estimate is
    let mut g = Frame::new(48, 36, 2.0, 12, |c| srgb_encode3(c * 0.3));
    g.l_r[5] = Vec3::splat(f32::NAN);
    g.l_rv[5] = Vec3::splat(f32::NAN);
    for method in [CmMethod::Statistics, CmMethod::Rohmer] {
        let out = cpu_frame(&g.input(), &params(method), 1.0, Composition::Additive, &mut CmState::default());
        assert!(out.composite.iter().enumerate().all(|(i, v)| i == 5 || v.is_finite()), "{method:?}");
    }
}

#[test]
fn scaled_composition_is_debevecs_ratio() {
    let photo = Vec3::new(0.4, 0.5, 0.6);
    let (m_rv, m_r) = (Vec3::new(0.2, 0.3, 0.4), Vec3::new(0.4, 0.6, 0.0));
    let out = compose(false, Composition::Scaled, photo, 1, m_rv, m_r);
    // α = cam/τ(L_r): 1 and 5/6; the blue channel has τ(L_r) = 0, so α = 1 there
    assert!((out - Vec3::new(0.2, 0.25, 1.0)).abs().max_element() < 1e-6, "{out}");
    let add = compose(false, Composition::Additive, photo, 1, m_rv, m_r);
    assert!((add - Vec3::new(0.2, 0.2, 1.0)).abs().max_element() < 1e-6, "{add}");
    // virtual pixels: α = 1, the camera is masked
    assert_eq!(compose(false, Composition::Scaled, photo, 2, m_rv, Vec3::ZERO), m_rv);
}

#[test]
fn a_virtual_pixel_shows_its_mapped_colour_whatever_the_mapping_of_black() {
    // an affine mapping with an offset maps L_r = 0 (a virtual pixel's real solution) to 0.35;
    // the virtual pixel must still show τ(L_rv), not τ(L_rv) − 0.35 (issue 17's dark objects)
    let (photo, m_rv, offset) = (Vec3::new(0.4, 0.5, 0.6), Vec3::new(0.6, 0.55, 0.5), Vec3::splat(0.35));
    for composition in [Composition::Additive, Composition::Scaled] {
        assert_eq!(compose(false, composition, photo, 2, m_rv, offset), m_rv);
    }
    // in the linear domain (Rohmer) the result is encoded again, as for any pixel
    let linear = compose(true, Composition::Additive, photo, 2, m_rv, offset);
    assert!((linear - crate::cm::colour::gamma_encode(m_rv)).abs().max_element() < 1e-6, "{linear}");
}

fn fixture_vec3s(value: &serde_json::Value, scale: f32) -> Vec<Vec3> {
    let f = |v: &serde_json::Value| v.as_f64().expect("a number") as f32 * scale;
    value.as_array().expect("an array").iter().map(|p| Vec3::new(f(&p[0]), f(&p[1]), f(&p[2]))).collect()
}

/// The statistics mapping against an independent computation (numpy 2.4.6 and colour-science
/// 0.4.7 on a 22×16 subsample of dir-lamp-box's gi+cm buffers, `tests/reference/cm_statistics.py`)
/// — means, ratios, both mapped buffers and the composite — and the diagnosis of docs/renderer.md
/// pinned: the real surfaces are achromatic, so the Lab a and b of TM(L_r) barely vary, the
/// ratios σ_cam/σ_r of eqs. 4.37–4.38 are far above 1 as specified, and the virtual red wall's
/// chroma is multiplied by them and clipped towards magenta.
#[test]
fn statistics_matches_an_independent_computation_on_dir_lamp_box() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/reference/cm_statistics.json");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).expect("cm_statistics.json")).expect("valid JSON");
    let s = &r["subsample"];
    let (width, height) = (s["width"].as_u64().unwrap() as u32, s["height"].as_u64().unwrap() as u32);
    let flags: Vec<u32> = s["flags"].as_array().unwrap().iter().map(|f| f.as_u64().unwrap() as u32).collect();
    let (l_r, l_rv) = (fixture_vec3s(&s["l_r"], 1.0), fixture_vec3s(&s["l_rv"], 1.0));
    let photo = fixture_vec3s(&s["photo_u8"], 1.0 / 255.0);
    let input = CmInput { width, height, l_rv: &l_rv, l_r: &l_r, flags: &flags, photo: &photo };
    let out = cpu_frame(&input, &params(CmMethod::Statistics), 1.0, Composition::Additive, &mut CmState::default());
    all_finite(&out);
    assert_eq!(out.report.pairs as u64, s["pixels_used"].as_u64().unwrap());
    assert!(out.report.fallback.is_none(), "{:?}", out.report.fallback);
    let warned = out.report.warning.as_ref().map(|w| w.channels.iter().map(|c| c.channel).collect::<Vec<_>>());
    assert_eq!(warned, Some(vec!["a", "b"]), "the chroma ratios are reported: {:?}", out.report.warning);
    let Mapping::Statistics { mean_source, mean_target, ratio } = out.report.mapping else {
        panic!("{:?}", out.report)
    };
    let want = |key: &str, c: usize| s[key][c].as_f64().unwrap() as f32;
    for c in 0..3 {
        assert!(
            (mean_source[c] - want("mean_source", c)).abs() < 2e-3,
            "μ_r {mean_source:?} against {}",
            s["mean_source"]
        );
        assert!(
            (mean_target[c] - want("mean_target", c)).abs() < 2e-3,
            "μ_cam {mean_target:?} against {}",
            s["mean_target"]
        );
        assert!((ratio[c] / want("ratio", c) - 1.0).abs() < 1e-3, "ratio {ratio:?} against {}", s["ratio"]);
    }
    for (name, got) in [("mapped_rv", &out.mapped_rv), ("mapped_r", &out.mapped_r), ("composite", &out.composite)] {
        for (i, (g, w)) in got.iter().zip(fixture_vec3s(&s[name], 1.0)).enumerate() {
            assert!((*g - w).abs().max_element() < 2e-3, "{name} at pixel {i}: {g} against {w}");
        }
    }
    // the diagnosis: lightness kept, chroma contrast multiplied by the camera's chroma noise
    assert!((0.8..1.25).contains(&ratio[0]) && ratio[1] > 10.0 && ratio[2] > 3.0, "{ratio:?}");
    let lab_of = |display: Vec3| linear_to_lab(srgb_decode3(display));
    let mut red = 0;
    for i in (0..flags.len()).filter(|&i| flags[i] == surface::VIRTUAL) {
        let (off, mapped) = (Mapping::Off.apply(l_rv[i], 1.0), out.mapped_rv[i]);
        if off.x > 1.5 * off.y && off.x > 1.5 * off.z {
            red += 1;
            // a* more than doubled, and clipped at the gamut's edge: red 1, green 0, more blue
            let (before, after) = (lab_of(off).y, lab_of(mapped).y);
            assert!(after > 2.0 * before, "red pixel {i}: a {before} → {after}");
            assert!(mapped.x > 0.999 && mapped.y < 1e-3 && mapped.z > off.z, "red pixel {i}: {off} → {mapped}");
        }
    }
    assert!(red >= 3, "the subsample has {red} red-wall pixels");
    // the real pixels that gi changes (the virtual box's shadow and bounce): the shift of a*
    // from the photograph is multiplied too (the green cast of gi+cm on the real box)
    let (mut shift_off, mut shift_cm, mut n) = (0.0, 0.0, 0);
    for i in (0..flags.len()).filter(|&i| flags[i] == surface::REAL && l_rv[i] != l_r[i]) {
        let off = compose(false, Composition::Additive, photo[i], flags[i], Mapping::Off.apply(l_rv[i], 1.0), {
            Mapping::Off.apply(l_r[i], 1.0)
        });
        shift_off += (lab_of(off).y - lab_of(photo[i]).y).abs();
        shift_cm += (lab_of(out.composite[i]).y - lab_of(photo[i]).y).abs();
        n += 1;
    }
    assert!(
        n >= 10 && shift_cm > 3.0 * shift_off,
        "{n} pixels: mean |Δa*| {} (off) against {} (cm)",
        shift_off / n as f32,
        shift_cm / n as f32
    );
}
