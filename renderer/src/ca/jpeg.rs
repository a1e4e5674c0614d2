//! The colour-space compression stage of the ca chain: JPEG's lossy part without the entropy
//! coding (which is lossless) — RGB to JFIF YCbCr, 8×8 DCT-II per block (aligned at the image
//! origin, borders by edge replication), quantisation with libjpeg's quality-scaled tables
//! (ITU T.81 Annex K.1/K.2, scaled as in libjpeg's `jpeg_quality_scaling`, the scaling the
//! `image` crate's encoder uses), dequantisation, inverse DCT and back to RGB. Chroma is not
//! subsampled (4:4:4). The DCT basis and the tables are built here once and handed to
//! `ca.wgsl`, which sums in the same order; rounding is floor(x + 0.5) on both sides.

use crate::image::Image;
use glam::Vec3;

/// ITU T.81 Table K.1 (luminance), natural (row-major) order.
pub const STD_LUMA: [u8; 64] = [
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56, 14, 17, 22, 29, 51,
    87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92, 49, 64, 78, 87, 103, 121, 120, 101,
    72, 92, 95, 98, 112, 100, 103, 99,
];
/// ITU T.81 Table K.2 (chrominance), natural order.
pub const STD_CHROMA: [u8; 64] = [
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99, 99, 99, 47, 66, 99, 99, 99,
    99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
    99, 99, 99, 99, 99, 99,
];

/// A table scaled to `quality` (1–100) as libjpeg does: s = 5000/q below 50, else 200 − 2q;
/// entries (t·s + 50)/100 clamped to [1, 255].
pub fn scaled_table(table: &[u8; 64], quality: u8) -> [f32; 64] {
    let q = quality.clamp(1, 100) as u32;
    let s = if q < 50 { 5000 / q } else { 200 - 2 * q };
    let mut out = [0.0f32; 64];
    for (o, &t) in out.iter_mut().zip(table) {
        *o = ((t as u32 * s + 50) / 100).clamp(1, 255) as f32;
    }
    out
}

/// The orthonormal DCT-II basis: `basis[u * 8 + x]` = c(u)/2 · cos((2x + 1)uπ/16), c(0) = 1/√2.
pub fn dct_basis() -> [f32; 64] {
    let mut b = [0.0f32; 64];
    for u in 0..8 {
        for x in 0..8 {
            let c = if u == 0 { std::f64::consts::FRAC_1_SQRT_2 } else { 1.0 };
            b[u * 8 + x] = (c / 2.0 * (((2 * x + 1) * u) as f64 * std::f64::consts::PI / 16.0).cos()) as f32;
        }
    }
    b
}

/// JFIF RGB (0–255) to level-shifted YCbCr.
#[inline]
pub fn to_ycc(c: Vec3) -> Vec3 {
    Vec3::new(
        0.299 * c.x + 0.587 * c.y + 0.114 * c.z - 128.0,
        -0.168_736 * c.x - 0.331_264 * c.y + 0.5 * c.z,
        0.5 * c.x - 0.418_688 * c.y - 0.081_312 * c.z,
    )
}

#[inline]
fn from_ycc(c: Vec3) -> Vec3 {
    let y = c.x + 128.0;
    Vec3::new(y + 1.402 * c.z, y - 0.344_136 * c.y - 0.714_136 * c.z, y + 1.772 * c.y)
}

/// Forward 8×8 DCT of one channel block `f[y * 8 + x]`: rows then columns, in this order.
pub fn dct8x8(f: &[f32; 64], basis: &[f32; 64]) -> [f32; 64] {
    let mut t = [0.0f32; 64]; // t[y*8+u]
    for y in 0..8 {
        for u in 0..8 {
            let mut s = 0.0f32;
            for x in 0..8 {
                s += basis[u * 8 + x] * f[y * 8 + x];
            }
            t[y * 8 + u] = s;
        }
    }
    let mut out = [0.0f32; 64]; // out[v*8+u]
    for v in 0..8 {
        for u in 0..8 {
            let mut s = 0.0f32;
            for y in 0..8 {
                s += basis[v * 8 + y] * t[y * 8 + u];
            }
            out[v * 8 + u] = s;
        }
    }
    out
}

fn idct8x8(coef: &[f32; 64], basis: &[f32; 64]) -> [f32; 64] {
    let mut t = [0.0f32; 64]; // t[v*8+x]
    for v in 0..8 {
        for x in 0..8 {
            let mut s = 0.0f32;
            for u in 0..8 {
                s += basis[u * 8 + x] * coef[v * 8 + u];
            }
            t[v * 8 + x] = s;
        }
    }
    let mut out = [0.0f32; 64];
    for y in 0..8 {
        for x in 0..8 {
            let mut s = 0.0f32;
            for v in 0..8 {
                s += basis[v * 8 + y] * t[v * 8 + x];
            }
            out[y * 8 + x] = s;
        }
    }
    out
}

/// The image (display-encoded, [0, 1]) after JPEG-style compression at `quality`, clamped to
/// [0, 1].
pub fn compress(img: &Image, quality: u8) -> Image {
    let basis = dct_basis();
    let tables =
        [scaled_table(&STD_LUMA, quality), scaled_table(&STD_CHROMA, quality), scaled_table(&STD_CHROMA, quality)];
    let (w, h) = (img.width as i64, img.height as i64);
    let mut out = Image::new(img.width, img.height);
    for by in (0..h).step_by(8) {
        for bx in (0..w).step_by(8) {
            let mut planes = [[0.0f32; 64]; 3];
            for y in 0..8 {
                for x in 0..8 {
                    let c = to_ycc(img.get_clamped(bx + x, by + y).clamp(Vec3::ZERO, Vec3::ONE) * 255.0).to_array();
                    for k in 0..3 {
                        planes[k][(y * 8 + x) as usize] = c[k];
                    }
                }
            }
            let mut rec = [[0.0f32; 64]; 3];
            for k in 0..3 {
                let mut coef = dct8x8(&planes[k], &basis);
                for (c, q) in coef.iter_mut().zip(&tables[k]) {
                    *c = (*c / q + 0.5).floor() * q;
                }
                rec[k] = idct8x8(&coef, &basis);
            }
            for y in 0..8 {
                for x in 0..8 {
                    if bx + x < w && by + y < h {
                        let j = (y * 8 + x) as usize;
                        let rgb = from_ycc(Vec3::new(rec[0][j], rec[1][j], rec[2][j])) * (1.0 / 255.0);
                        out.set((bx + x) as u32, (by + y) as u32, rgb.clamp(Vec3::ZERO, Vec3::ONE));
                    }
                }
            }
        }
    }
    out
}
