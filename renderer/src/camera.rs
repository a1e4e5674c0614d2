//! The pinhole camera: intrinsics (a K matrix, or a vertical field of view) and pose.
//! Camera space is right-handed, x right, y up, looking down −z; image rows go top to bottom,
//! so pixel (u, v) maps to x = (u − cx)/fx, y = −(v − cy)/fy. Lens distortion is not here: it is
//! a stage of the simulated camera ([`crate::sensor`]), applied to the rendered image.

use crate::geometry::Ray;
use glam::{Mat3, Vec3};

#[derive(Clone, Debug)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub position: Vec3,
    /// Columns: camera right, up, backward, in world space.
    pub rotation: Mat3,
}

impl Camera {
    /// Vertical field of view in degrees, principal point at the image centre.
    pub fn from_fov(width: u32, height: u32, fov_y_deg: f32, position: Vec3, look_at: Vec3, up: Vec3) -> Self {
        let fy = 0.5 * height as f32 / (0.5 * fov_y_deg.to_radians()).tan();
        Camera::from_k(width, height, [fy, fy, width as f32 / 2.0, height as f32 / 2.0], position, look_at, up)
    }
    /// K given as (fx, fy, cx, cy) in pixels.
    pub fn from_k(width: u32, height: u32, k: [f32; 4], position: Vec3, look_at: Vec3, up: Vec3) -> Self {
        let back = (position - look_at).normalize();
        let right = up.cross(back).normalize();
        let true_up = back.cross(right);
        Camera {
            width,
            height,
            fx: k[0],
            fy: k[1],
            cx: k[2],
            cy: k[3],
            position,
            rotation: Mat3::from_cols(right, true_up, back),
        }
    }
    /// The same camera at another resolution (intrinsics scaled with the image).
    pub fn resized(&self, width: u32, height: u32) -> Camera {
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        Camera { width, height, fx: self.fx * sx, fy: self.fy * sy, cx: self.cx * sx, cy: self.cy * sy, ..self.clone() }
    }
    pub fn fov_y_deg(&self) -> f32 {
        2.0 * (0.5 * self.height as f32 / self.fy).atan().to_degrees()
    }
    /// The primary ray through continuous pixel coordinates (pixel centres at +0.5).
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let d = Vec3::new((px - self.cx) / self.fx, -(py - self.cy) / self.fy, -1.0);
        Ray { origin: self.position, dir: (self.rotation * d).normalize() }
    }
    /// Projects a world point to pixel coordinates (None when behind the camera).
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let c = self.rotation.transpose() * (p - self.position);
        if c.z >= 0.0 {
            return None;
        }
        Some((self.cx + self.fx * c.x / -c.z, self.cy - self.fy * c.y / -c.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_ray() {
        let cam = Camera::from_fov(64, 48, 50.0, Vec3::new(0.3, 0.4, 0.5), Vec3::ZERO, Vec3::Y);
        let r = cam.ray(10.5, 30.25);
        let (u, v) = cam.project(r.origin + r.dir * 2.0).unwrap();
        assert!((u - 10.5).abs() < 1e-3 && (v - 30.25).abs() < 1e-3);
        let (u, v) = cam.project(Vec3::ZERO).unwrap();
        assert!((u - 32.0).abs() < 1e-3 && (v - 24.0).abs() < 1e-3);
        assert!((cam.fov_y_deg() - 50.0).abs() < 1e-3);
    }
}
