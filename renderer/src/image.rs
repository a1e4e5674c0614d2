//! Images: linear (or display-encoded) RGB float images and scalar masks, with PNG and EXR
//! input and output. Which space an [`Image`] holds is the caller's contract: HDR buffers are
//! linear scene radiance; camera output is display-encoded sRGB in [0, 1].

use crate::error::{RenderError, Result};
use glam::Vec3;
use std::path::Path;

/// An RGB image of `f32` triples, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

/// A display-encoded image in 8 bits a channel: RGBA bytes, row-major, top row first, 4 bytes
/// a pixel, alpha 255; each channel as [`quantize8`] rounds it (what a live frame that is only
/// shown reads back from the GPU, [`crate::gpu::DirRenderer::render_display`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgba8 {
    pub width: u32,
    pub height: u32,
    pub bytes: Vec<u8>,
}

impl Rgba8 {
    /// `image` (display-encoded) quantised as [`Image::to_rgb8`] does, alpha 255.
    pub fn from_image(image: &Image) -> Rgba8 {
        let bytes = image.pixels.iter().flat_map(|p| [quantize8(p.x), quantize8(p.y), quantize8(p.z), 255]).collect();
        Rgba8 { width: image.width, height: image.height, bytes }
    }

    /// The RGB bytes, alpha dropped: [`Image::to_rgb8`] of the image these bytes came from.
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.bytes.chunks_exact(4).flat_map(|c| [c[0], c[1], c[2]]).collect()
    }
}

/// A scalar image (coverage, region, error map), row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    pub width: u32,
    pub height: u32,
    pub values: Vec<f32>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image { width, height, pixels: vec![Vec3::ZERO; (width * height) as usize] }
    }
    pub fn filled(width: u32, height: u32, value: Vec3) -> Self {
        Image { width, height, pixels: vec![value; (width * height) as usize] }
    }
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: Vec3) {
        self.pixels[(y * self.width + x) as usize] = v;
    }
    /// Clamped-to-edge fetch with signed coordinates.
    #[inline]
    pub fn get_clamped(&self, x: i64, y: i64) -> Vec3 {
        let x = x.clamp(0, self.width as i64 - 1) as u32;
        let y = y.clamp(0, self.height as i64 - 1) as u32;
        self.get(x, y)
    }
    /// Bilinear sample at continuous pixel coordinates (pixel centres at +0.5), clamped to edge.
    pub fn sample_bilinear(&self, px: f32, py: f32) -> Vec3 {
        let x = px - 0.5;
        let y = py - 0.5;
        let x0 = x.floor();
        let y0 = y.floor();
        let fx = x - x0;
        let fy = y - y0;
        let (x0, y0) = (x0 as i64, y0 as i64);
        let a = self.get_clamped(x0, y0);
        let b = self.get_clamped(x0 + 1, y0);
        let c = self.get_clamped(x0, y0 + 1);
        let d = self.get_clamped(x0 + 1, y0 + 1);
        a.lerp(b, fx).lerp(c.lerp(d, fx), fy)
    }
    pub fn map(&self, f: impl Fn(Vec3) -> Vec3) -> Image {
        Image { width: self.width, height: self.height, pixels: self.pixels.iter().map(|&p| f(p)).collect() }
    }
    /// Nearest-neighbour-free resize by bilinear sampling (for photographs and previews).
    pub fn resized(&self, width: u32, height: u32) -> Image {
        let mut out = Image::new(width, height);
        let sx = self.width as f32 / width as f32;
        let sy = self.height as f32 / height as f32;
        for y in 0..height {
            for x in 0..width {
                out.set(x, y, self.sample_bilinear((x as f32 + 0.5) * sx, (y as f32 + 0.5) * sy));
            }
        }
        out
    }
    pub fn mean(&self) -> Vec3 {
        let n = self.pixels.len().max(1) as f64;
        let s = self.pixels.iter().fold([0.0f64; 3], |a, p| [a[0] + p.x as f64, a[1] + p.y as f64, a[2] + p.z as f64]);
        Vec3::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }
    /// Counts of NaN, infinite and negative channel values.
    pub fn count_invalid(&self) -> (usize, usize, usize) {
        let mut nan = 0;
        let mut inf = 0;
        let mut neg = 0;
        for p in &self.pixels {
            for c in p.to_array() {
                if c.is_nan() {
                    nan += 1
                } else if c.is_infinite() {
                    inf += 1
                } else if c < 0.0 {
                    neg += 1
                }
            }
        }
        (nan, inf, neg)
    }

    /// Encodes a linear image to sRGB (no tone mapping; values are clamped to [0, 1]).
    pub fn linear_to_srgb(&self) -> Image {
        self.map(|p| Vec3::new(srgb_encode(p.x), srgb_encode(p.y), srgb_encode(p.z)))
    }
    pub fn srgb_to_linear(&self) -> Image {
        self.map(|p| Vec3::new(srgb_decode(p.x), srgb_decode(p.y), srgb_decode(p.z)))
    }
    /// 8-bit RGB bytes of a display-encoded image (values clamped to [0, 1], rounded).
    pub fn to_rgb8(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            for c in p.to_array() {
                out.push(quantize8(c));
            }
        }
        out
    }
    pub fn from_rgb8(width: u32, height: u32, bytes: &[u8]) -> Image {
        let pixels = bytes
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0] as f32 / 255.0, c[1] as f32 / 255.0, c[2] as f32 / 255.0))
            .collect();
        Image { width, height, pixels }
    }

    /// Writes a display-encoded image as 8-bit PNG.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        image::save_buffer(path, &self.to_rgb8(), self.width, self.height, image::ExtendedColorType::Rgb8)
            .map_err(|e| RenderError::Write { path: path.to_owned(), reason: e.to_string() })
    }
    /// A display-encoded image as the bytes of an 8-bit PNG file.
    pub fn encode_png(&self) -> Vec<u8> {
        let mut bytes = std::io::Cursor::new(Vec::new());
        image::write_buffer_with_format(
            &mut bytes,
            &self.to_rgb8(),
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .expect("PNG encoding into memory of a buffer of the right size cannot fail");
        bytes.into_inner()
    }
    /// Writes a linear image as 32-bit float EXR.
    pub fn save_exr(&self, path: &Path) -> Result<()> {
        let data: Vec<f32> = self.pixels.iter().flat_map(|p| p.to_array()).collect();
        let buf = image::Rgb32FImage::from_raw(self.width, self.height, data)
            .ok_or_else(|| RenderError::Write { path: path.to_owned(), reason: "bad buffer size".into() })?;
        buf.save_with_format(path, image::ImageFormat::OpenExr)
            .map_err(|e| RenderError::Write { path: path.to_owned(), reason: e.to_string() })
    }
    /// Loads an image file. HDR formats (`.hdr`, `.exr`) are returned as stored (linear);
    /// 8/16-bit formats are returned as stored too (display-encoded): convert with
    /// [`Image::srgb_to_linear`] where linear values are needed.
    pub fn load(path: &Path, what: &'static str) -> Result<Image> {
        let img = image::open(path).map_err(|e| RenderError::MissingFile {
            what,
            path: path.to_owned(),
            reason: e.to_string(),
        })?;
        let rgb = img.into_rgb32f();
        let (w, h) = rgb.dimensions();
        let pixels = rgb.pixels().map(|p| Vec3::new(p.0[0], p.0[1], p.0[2])).collect();
        Ok(Image { width: w, height: h, pixels })
    }
    /// True when the file extension names a linear HDR format.
    pub fn is_hdr_path(path: &Path) -> bool {
        matches!(
            path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref(),
            Some("hdr") | Some("exr")
        )
    }
}

impl Mask {
    pub fn new(width: u32, height: u32) -> Self {
        Mask { width, height, values: vec![0.0; (width * height) as usize] }
    }
    /// Fraction of pixels with a value above 0.5.
    pub fn coverage(&self) -> f32 {
        self.values.iter().filter(|&&v| v > 0.5).count() as f32 / self.values.len().max(1) as f32
    }
    pub fn to_image(&self) -> Image {
        Image { width: self.width, height: self.height, pixels: self.values.iter().map(|&v| Vec3::splat(v)).collect() }
    }
    pub fn save_png(&self, path: &Path) -> Result<()> {
        self.to_image().save_png(path)
    }
}

#[inline]
pub fn quantize8(c: f32) -> u8 {
    if c.is_nan() { 0 } else { (c.clamp(0.0, 1.0) * 255.0).round() as u8 }
}

/// The sRGB transfer function (linear → display).
#[inline]
pub fn srgb_encode(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// The inverse sRGB transfer function (display → linear).
#[inline]
pub fn srgb_decode(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.040_45 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Writes an image by extension: `.exr` as linear float, anything else as 8-bit PNG. `linear` is
/// the linear version (for EXR) and `display` the display-encoded one (for PNG).
pub fn save_by_extension(path: &Path, linear: &Image, display: &Image) -> Result<()> {
    // the output's folder is made if missing (`--out renders/gi.png`)
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| RenderError::Write {
            path: path.to_owned(),
            reason: format!("cannot create its folder: {e}"),
        })?;
    }
    if path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        linear.save_exr(path)
    } else {
        display.save_png(path)
    }
}

/// Makes the buffers folder `dir` (and its parents) if missing.
pub fn create_buffers_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| RenderError::Write { path: dir.to_owned(), reason: e.to_string() })
}

/// Writes `value` as pretty JSON (with a final newline) to `path`: the `report.json` of a
/// buffers folder.
pub fn save_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("JSON values serialise") + "\n";
    std::fs::write(path, text).map_err(|e| RenderError::Write { path: path.to_owned(), reason: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 8-bit frame a live frame hands on has the bytes the old conversion gave the lab: the
    /// read-back bytes made an image of b / 255, quantised again by `Image::to_rgb8` — for
    /// every byte value, in every channel.
    #[test]
    fn rgba8_bytes_are_those_of_the_old_conversion_through_floats() {
        let bytes: Vec<u8> = (0..=255u8).flat_map(|b| [b, 255 - b, b / 3, 255]).collect();
        let frame = Rgba8 { width: 16, height: 16, bytes };
        // the old path: each byte / 255 as an image, then `to_rgb8`
        let channel = |b: u8| b as f32 / 255.0;
        let pixels = frame.bytes.chunks_exact(4).map(|c| Vec3::new(channel(c[0]), channel(c[1]), channel(c[2])));
        let image = Image { width: 16, height: 16, pixels: pixels.collect() };
        assert_eq!(frame.to_rgb8(), image.to_rgb8());
        assert_eq!(Rgba8::from_image(&image), frame);
    }
}
