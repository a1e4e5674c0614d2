//! Colour conversions the colour-mapping methods share, each mirrored line for line in the WGSL
//! of `gpu/cm.wgsl` and `gpu/compose.wgsl`: the simplified Reinhard tone mapping, sRGB and
//! gamma-2.2 transfer curves, HSV, CIELab with illuminant E (linear sRGB primaries with XYZ
//! scaled so that RGB white maps to XYZ white, the "white maps to white" conversion of thesis
//! 4.5.3), and the CIEDE2000 colour difference (Sharma, Wu & Dalal 2005) used by the accuracy
//! benchmark. Tested against colour-science 0.4.7 and Sharma's published test pairs
//! (`renderer/tests/reference/cm_colour.py` → `cm_colour.json`).

use glam::Vec3;

pub use crate::image::{srgb_decode, srgb_encode};

/// Linear sRGB → XYZ with illuminant E by XYZ scaling: colour-science 0.4.7,
/// `RGB_to_XYZ(rgb, "sRGB", illuminant=E, chromatic_adaptation_transform="XYZ Scaling")`,
/// columns are the images of pure red, green and blue (printed by `cm_colour.py`).
pub const RGB_TO_XYZ_E: [[f32; 3]; 3] =
    [[0.433_897_03, 0.376_240_5, 0.189_908_86], [0.2126, 0.7152, 0.0722], [0.017_721_742, 0.109_452_41, 0.872_772_8]];
/// Its inverse (numpy.linalg.inv of the matrix above).
#[allow(clippy::excessive_precision)]
pub const XYZ_E_TO_RGB: [[f32; 3]; 3] = [
    [3.080_071_7, -1.537_208, -0.543_035_34],
    [-0.920_925_94, 1.875_756, 0.045_214_98],
    [0.052_950_014, -0.204_021_05, 1.151_129_6],
];

fn mat_vec(m: &[[f32; 3]; 3], v: Vec3) -> Vec3 {
    Vec3::new(
        m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
        m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
        m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
    )
}

/// The simplified Reinhard operator per channel, x·e / (1 + x·e) with negative input clamped
/// to 0; linear output in [0, 1).
pub fn tone_map(x: Vec3, exposure: f32) -> Vec3 {
    let x = x.max(Vec3::ZERO) * exposure;
    x / (Vec3::ONE + x)
}

/// sRGB encoding per channel (input clamped to [0, 1]).
pub fn srgb_encode3(c: Vec3) -> Vec3 {
    Vec3::new(srgb_encode(c.x), srgb_encode(c.y), srgb_encode(c.z))
}

/// sRGB decoding per channel (input clamped to [0, 1]).
pub fn srgb_decode3(c: Vec3) -> Vec3 {
    Vec3::new(srgb_decode(c.x), srgb_decode(c.y), srgb_decode(c.z))
}

/// Rohmer et al.'s linearisation of camera values: a gamma of 2.2 (their Section 4.1).
pub fn gamma_decode(c: Vec3) -> Vec3 {
    c.max(Vec3::ZERO).powf(2.2)
}

/// The inverse of [`gamma_decode`], input clamped to [0, 1].
pub fn gamma_encode(c: Vec3) -> Vec3 {
    c.clamp(Vec3::ZERO, Vec3::ONE).powf(1.0 / 2.2)
}

/// CIELab's f(t) (CIE 15: cube root above (6/29)³, linear below).
fn lab_f(t: f32) -> f32 {
    const D: f32 = 6.0 / 29.0;
    if t > D * D * D { t.cbrt() } else { t / (3.0 * D * D) + 4.0 / 29.0 }
}

fn lab_f_inv(t: f32) -> f32 {
    const D: f32 = 6.0 / 29.0;
    if t > D { t * t * t } else { 3.0 * D * D * (t - 4.0 / 29.0) }
}

/// Linear RGB → CIELab with illuminant E (white (1, 1, 1) → L = 100, a = b = 0).
pub fn linear_to_lab(rgb: Vec3) -> Vec3 {
    let xyz = mat_vec(&RGB_TO_XYZ_E, rgb);
    let (fx, fy, fz) = (lab_f(xyz.x), lab_f(xyz.y), lab_f(xyz.z));
    Vec3::new(116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz))
}

/// CIELab (illuminant E) → linear RGB; the exact inverse of [`linear_to_lab`].
pub fn lab_to_linear(lab: Vec3) -> Vec3 {
    let fy = (lab.x + 16.0) / 116.0;
    let fx = fy + lab.y / 500.0;
    let fz = fy - lab.z / 200.0;
    mat_vec(&XYZ_E_TO_RGB, Vec3::new(lab_f_inv(fx), lab_f_inv(fy), lab_f_inv(fz)))
}

/// HSV of a non-negative RGB colour: (hue in [0, 1), saturation in [0, 1], value = max).
/// Grey (and black) has hue 0 and saturation 0.
pub fn hsv(c: Vec3) -> Vec3 {
    let c = c.max(Vec3::ZERO);
    let max = c.x.max(c.y).max(c.z);
    let min = c.x.min(c.y).min(c.z);
    let delta = max - min;
    if delta <= 0.0 || max <= 0.0 {
        return Vec3::new(0.0, 0.0, max);
    }
    let mut h = if max == c.x {
        (c.y - c.z) / delta
    } else if max == c.y {
        (c.z - c.x) / delta + 2.0
    } else {
        (c.x - c.y) / delta + 4.0
    };
    h /= 6.0;
    if h < 0.0 {
        h += 1.0;
    }
    if h >= 1.0 {
        h -= 1.0;
    }
    Vec3::new(h, delta / max, max)
}

/// The circular distance of two hues in [0, 1): in [0, 0.5].
pub fn hue_distance(a: f32, b: f32) -> f32 {
    let d = (a - b).abs();
    d.min(1.0 - d)
}

/// CIEDE2000 (k_L = k_C = k_H = 1) after Sharma, Wu & Dalal (2005), in f64.
pub fn ciede2000(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    use std::f64::consts::PI;
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let c1 = (a1 * a1 + b1 * b1).sqrt();
    let c2 = (a2 * a2 + b2 * b2).sqrt();
    let c_bar7 = ((c1 + c2) / 2.0).powi(7);
    let g = 0.5 * (1.0 - (c_bar7 / (c_bar7 + 25f64.powi(7))).sqrt());
    let (a1p, a2p) = ((1.0 + g) * a1, (1.0 + g) * a2);
    let (c1p, c2p) = ((a1p * a1p + b1 * b1).sqrt(), (a2p * a2p + b2 * b2).sqrt());
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            let h = b.atan2(a).to_degrees();
            if h < 0.0 { h + 360.0 } else { h }
        }
    };
    let (h1p, h2p) = (hue(b1, a1p), hue(b2, a2p));
    let dl = l2 - l1;
    let dc = c2p - c1p;
    let dh = if c1p * c2p == 0.0 {
        0.0
    } else if (h2p - h1p).abs() <= 180.0 {
        h2p - h1p
    } else if h2p - h1p > 180.0 {
        h2p - h1p - 360.0
    } else {
        h2p - h1p + 360.0
    };
    let d_h = 2.0 * (c1p * c2p).sqrt() * (dh.to_radians() / 2.0).sin();
    let l_bar = (l1 + l2) / 2.0;
    let c_bar_p = (c1p + c2p) / 2.0;
    let h_bar = if c1p * c2p == 0.0 {
        h1p + h2p
    } else if (h1p - h2p).abs() <= 180.0 {
        (h1p + h2p) / 2.0
    } else if h1p + h2p < 360.0 {
        (h1p + h2p + 360.0) / 2.0
    } else {
        (h1p + h2p - 360.0) / 2.0
    };
    let t = 1.0 - 0.17 * (h_bar - 30.0).to_radians().cos()
        + 0.24 * (2.0 * h_bar).to_radians().cos()
        + 0.32 * (3.0 * h_bar + 6.0).to_radians().cos()
        - 0.20 * (4.0 * h_bar - 63.0).to_radians().cos();
    let d_theta = 30.0 * (-((h_bar - 275.0) / 25.0).powi(2)).exp();
    let c_bar_p7 = c_bar_p.powi(7);
    let r_c = 2.0 * (c_bar_p7 / (c_bar_p7 + 25f64.powi(7))).sqrt();
    let s_l = 1.0 + 0.015 * (l_bar - 50.0).powi(2) / (20.0 + (l_bar - 50.0).powi(2)).sqrt();
    let s_c = 1.0 + 0.045 * c_bar_p;
    let s_h = 1.0 + 0.015 * c_bar_p * t;
    let r_t = -(2.0 * d_theta * PI / 180.0).sin() * r_c;
    let (x, y, z) = (dl / s_l, dc / s_c, d_h / s_h);
    (x * x + y * y + z * z + r_t * y * z).max(0.0).sqrt()
}

/// CIEDE2000 between two display-encoded (sRGB) colours, through CIELab with illuminant E.
pub fn ciede2000_display(a: Vec3, b: Vec3) -> f64 {
    let la = linear_to_lab(srgb_decode3(a));
    let lb = linear_to_lab(srgb_decode3(b));
    ciede2000([la.x as f64, la.y as f64, la.z as f64], [lb.x as f64, lb.y as f64, lb.z as f64])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference() -> serde_json::Value {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/reference/cm_colour.json");
        serde_json::from_str(&std::fs::read_to_string(path).expect("cm_colour.json")).expect("valid JSON")
    }

    fn arr(v: &serde_json::Value) -> [f64; 3] {
        let a = v.as_array().unwrap();
        [a[0].as_f64().unwrap(), a[1].as_f64().unwrap(), a[2].as_f64().unwrap()]
    }

    #[test]
    fn ciede2000_matches_sharmas_34_published_pairs_and_colour_science() {
        let r = reference();
        for (i, pair) in r["sharma"].as_array().unwrap().iter().enumerate() {
            let d = ciede2000(arr(&pair["lab1"]), arr(&pair["lab2"]));
            let published = pair["published"].as_f64().unwrap();
            assert!((d - published).abs() < 1e-4, "Sharma pair {}: {d} against {published}", i + 1);
            assert!(
                (ciede2000(arr(&pair["lab2"]), arr(&pair["lab1"])) - published).abs() < 1e-4,
                "pair {} is not symmetric",
                i + 1
            );
        }
        for pair in r["random"].as_array().unwrap() {
            let d = ciede2000(arr(&pair["lab1"]), arr(&pair["lab2"]));
            let want = pair["colour_science"].as_f64().unwrap();
            assert!((d - want).abs() < 1e-9 * want.max(1.0), "{d} against colour-science {want}");
        }
    }

    #[test]
    fn lab_with_illuminant_e_matches_colour_science_and_inverts() {
        for e in reference()["linear_rgb_to_lab_e"].as_array().unwrap() {
            let rgb = arr(&e["rgb"]);
            let want = arr(&e["lab"]);
            let lab = linear_to_lab(Vec3::new(rgb[0] as f32, rgb[1] as f32, rgb[2] as f32));
            for k in 0..3 {
                assert!((lab[k] as f64 - want[k]).abs() < 2e-3, "{rgb:?}: {lab} against {want:?}");
            }
            let back = lab_to_linear(lab);
            for k in 0..3 {
                assert!((back[k] as f64 - rgb[k]).abs() < 1e-4 * rgb[k].max(1.0), "{rgb:?} round trip gives {back}");
            }
        }
    }

    #[test]
    fn hsv_of_primaries_greys_and_hdr() {
        assert_eq!(hsv(Vec3::new(1.0, 0.0, 0.0)), Vec3::new(0.0, 1.0, 1.0));
        assert!((hsv(Vec3::new(0.0, 1.0, 0.0)).x - 1.0 / 3.0).abs() < 1e-6);
        assert!((hsv(Vec3::new(0.0, 0.0, 1.0)).x - 2.0 / 3.0).abs() < 1e-6);
        assert!((hsv(Vec3::new(1.0, 0.0, 0.5)).x - 11.0 / 12.0).abs() < 1e-6);
        assert_eq!(hsv(Vec3::splat(0.4)), Vec3::new(0.0, 0.0, 0.4));
        assert_eq!(hsv(Vec3::ZERO), Vec3::ZERO);
        // scale-invariant hue and saturation, above 1 too
        let (a, b) = (hsv(Vec3::new(0.3, 0.2, 0.1)), hsv(Vec3::new(6.0, 4.0, 2.0)));
        assert!((a.x - b.x).abs() < 1e-6 && (a.y - b.y).abs() < 1e-6 && b.z == 6.0);
        assert!((hue_distance(0.95, 0.05) - 0.1).abs() < 1e-6);
    }
}
