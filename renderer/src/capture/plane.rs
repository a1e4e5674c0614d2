//! Least-squares plane fitting by Cramer's rule (Rohmer et al., Sec. 5): the samples are
//! shifted to their mean; for each axis a the normal is assumed to have n_a = 1 and the other two
//! components solve a 2×2 normal-equation system; of the three systems the one with the largest
//! determinant (the best-conditioned: its axis is closest to the true normal) is solved. A fit
//! fails with two or fewer samples or when even the largest determinant is negligible against
//! the samples' spread (collinear or coincident samples).

use glam::{DVec3, Vec3};

/// A fitted plane: a point on it (the samples' mean) and its unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub point: Vec3,
    pub normal: Vec3,
}

/// Why a plane could not be fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitFailure {
    /// Two or fewer samples.
    TooFew,
    /// The largest of the three determinants is negligible: the samples lie on a line or a point.
    IllConditioned,
}

/// A relative determinant below this is ill-conditioned (against the square of the samples'
/// second moment, so the test does not depend on the scene's scale).
const DET_EPSILON: f64 = 1e-10;

/// Fits a plane to `points` (world positions). Accumulates in f64 (a plane of samples a few
/// metres away with millimetre noise loses its normal in f32 moment sums).
pub fn fit_plane(points: &[Vec3]) -> Result<Plane, FitFailure> {
    if points.len() <= 2 {
        return Err(FitFailure::TooFew);
    }
    let n = points.len() as f64;
    let mean = points.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / n;
    // second moments of the shifted samples
    let (mut xx, mut xy, mut xz, mut yy, mut yz, mut zz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let d = p.as_dvec3() - mean;
        xx += d.x * d.x;
        xy += d.x * d.y;
        xz += d.x * d.z;
        yy += d.y * d.y;
        yz += d.y * d.z;
        zz += d.z * d.z;
    }
    // n_z = 1: [xx xy; xy yy] [nx ny]ᵀ = −[xz yz]ᵀ, and likewise for n_x = 1 and n_y = 1
    let det_z = xx * yy - xy * xy;
    let det_x = yy * zz - yz * yz;
    let det_y = xx * zz - xz * xz;
    let spread = xx + yy + zz;
    let best = det_x.max(det_y).max(det_z);
    if !(best > DET_EPSILON * spread * spread) {
        return Err(FitFailure::IllConditioned);
    }
    let normal = if best == det_z {
        DVec3::new((-xz * yy + yz * xy) / det_z, (-yz * xx + xz * xy) / det_z, 1.0)
    } else if best == det_x {
        DVec3::new(1.0, (-xy * zz + xz * yz) / det_x, (-xz * yy + xy * yz) / det_x)
    } else {
        DVec3::new((-xy * zz + yz * xz) / det_y, 1.0, (-yz * xx + xy * xz) / det_y)
    };
    Ok(Plane { point: mean.as_vec3(), normal: normal.normalize().as_vec3() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Frame, Rng, sample_uniform_sphere};

    fn samples_on(normal: Vec3, point: Vec3, n: usize, noise: f32, rng: &mut Rng) -> Vec<Vec3> {
        let frame = Frame::from_normal(normal);
        (0..n)
            .map(|_| {
                let (a, b) = (rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0);
                point + frame.t * (0.1 * a) + frame.b * (0.1 * b) + normal * (noise * rng.next_normal())
            })
            .collect()
    }

    /// The angle between two lines (atan2 of the cross and dot products: no f32 acos floor).
    fn angle_deg(a: Vec3, b: Vec3) -> f32 {
        a.cross(b).length().atan2(a.dot(b).abs()).to_degrees()
    }

    #[test]
    fn exact_samples_give_the_analytic_plane_in_every_orientation() {
        let mut rng = Rng::new(1);
        // random normals, and the three the n_z = 1 system cannot express (normals in the xy
        // plane: its determinant is zero there) and the axes themselves
        let mut normals: Vec<Vec3> = (0..200).map(|_| sample_uniform_sphere(rng.next_f32(), rng.next_f32())).collect();
        normals.extend([Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(1.0, 1.0, 0.0).normalize(), Vec3::new(0.6, -0.8, 0.0)]);
        for normal in normals {
            let point = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
            let pts = samples_on(normal, point, 12, 0.0, &mut rng);
            let plane = fit_plane(&pts).expect("a plane");
            assert!(angle_deg(plane.normal, normal) < 0.01, "normal {normal} fitted {}", plane.normal);
            assert!((plane.point - point).dot(normal).abs() < 1e-5, "the mean lies on the plane");
            assert!((plane.normal.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn the_determinant_cases_are_chosen_by_size() {
        // a normal exactly in the xy plane: det_z = 0, and the fit must still be exact
        let pts = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 1.0),
            Vec3::new(0.5, -0.5, 0.3),
        ];
        let plane = fit_plane(&pts).unwrap();
        assert!(angle_deg(plane.normal, Vec3::new(1.0, 1.0, 0.0).normalize()) < 1e-4, "{}", plane.normal);
    }

    #[test]
    fn noisy_samples_fit_within_the_noise_and_degenerate_sets_are_refused() {
        let mut rng = Rng::new(2);
        let mut errors: Vec<f32> = (0..300)
            .map(|_| {
                let normal = sample_uniform_sphere(rng.next_f32(), rng.next_f32());
                let pts = samples_on(normal, Vec3::new(0.0, 0.0, -3.0), 16, 0.002, &mut rng);
                angle_deg(fit_plane(&pts).unwrap().normal, normal)
            })
            .collect();
        errors.sort_by(f32::total_cmp);
        // 2 mm noise over a 20 cm patch of 16 samples: about a degree
        assert!(errors[150] < 1.5 && errors[290] < 4.0, "median {} p97 {}", errors[150], errors[290]);
        assert_eq!(fit_plane(&[Vec3::ZERO, Vec3::X]), Err(FitFailure::TooFew));
        assert_eq!(fit_plane(&[]), Err(FitFailure::TooFew));
        let line: Vec<Vec3> = (0..10).map(|i| Vec3::new(1.0, 2.0, 3.0) * i as f32).collect();
        assert_eq!(fit_plane(&line), Err(FitFailure::IllConditioned));
        assert_eq!(fit_plane(&[Vec3::ONE; 5]), Err(FitFailure::IllConditioned));
    }
}
