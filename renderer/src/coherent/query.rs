//! The environment queries of Rohmer et al.'s Sec. 6 behind one interface (their Fig. 5): a ray
//! or cone from a point into the captured real scene returns the radiance arriving along it and
//! the distance to what sent it. Environment mapping (EM) reads the distance impostor in the
//! query's direction as if seen from the impostor's centre; distance impostor tracing (DIT)
//! searches along the ray; voxel cone tracing (VCT) marches the scene voxel volume. What the
//! capture did not reach (beyond the depth sensor's range: the sky, a window) is answered by the
//! scene's environment light, as the thesis's fish-eye capture of the surroundings would.

use super::solid::{SolidHit, SolidVolume};
use crate::coherent::impostor::DistanceImpostor;
use crate::coherent::voxel::VoxelVolume;
use crate::light::Environment;
use glam::Vec3;
use std::sync::Arc;

/// How the environment is queried.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Query {
    /// Environment mapping: the impostor's radiance in the ray's direction, its distance for
    /// occlusion tests.
    Em,
    /// Distance impostor tracing: the ray's intersection searched in the impostor.
    Dit,
    /// Voxel cone tracing in the scene voxel volume.
    Vct,
}

/// Linear-search and secant steps of impostor tracing (those `mrstudy capture` evaluates).
pub const DIT_STEPS: u32 = 24;
pub const DIT_REFINEMENTS: u32 = 6;

/// Radiance arriving along a query and the distance to its source (infinite for the
/// environment light beyond the capture).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    pub radiance: Vec3,
    pub distance: f32,
}

/// The scene representations a query reads.
#[derive(Clone, Debug, Default)]
pub struct Representation {
    /// One distance impostor per virtual object, centred in it (EM, DIT); a query reads the
    /// one whose centre is nearest its origin, so that no query starts far from the centre its
    /// parallax correction assumes.
    pub impostors: Vec<DistanceImpostor>,
    /// The scene voxel volume (VCT); shared, as it does not depend on the virtual object.
    pub voxels: Option<Arc<VoxelVolume>>,
    /// The environment light beyond the capture.
    pub sky: Option<Arc<Environment>>,
    /// Each virtual object's solid volume (self-shadows; empty when none are tested).
    pub solids: Vec<SolidVolume>,
    /// Self-shadow rays intersect the objects exactly: some virtual object is not closed, so
    /// it has no solid volume.
    pub exact_self_shadows: bool,
}

impl Representation {
    fn sky(&self, dir: Vec3) -> Vec3 {
        self.sky.as_ref().map_or(Vec3::ZERO, |env| env.eval(dir))
    }

    /// The impostor whose centre is nearest `origin` (None when none was built).
    pub fn impostor_near(&self, origin: Vec3) -> Option<&DistanceImpostor> {
        self.impostors.iter().min_by(|a, b| {
            let (da, db) = ((a.centre - origin).length_squared(), (b.centre - origin).length_squared());
            da.total_cmp(&db)
        })
    }

    /// The radiance arriving at `origin` from the unit direction `dir`, by `query`; a cone of
    /// half-angle `half_angle` for VCT (rays ignore it). A query whose representation was not
    /// built falls back to impostor tracing, then to the environment light alone.
    pub fn incident(&self, query: Query, origin: Vec3, dir: Vec3, half_angle: f32) -> Incident {
        match (query, self.impostor_near(origin), &self.voxels) {
            (Query::Vct, _, Some(voxels)) => {
                let hit = voxels.cone(origin, dir, half_angle);
                Incident { radiance: hit.radiance + (1.0 - hit.opacity) * self.sky(dir), distance: hit.distance }
            }
            (Query::Em, Some(map), _) => match map.lookup(dir) {
                Some(hit) => Incident { radiance: hit.radiance, distance: (hit.point - origin).length() },
                None => Incident { radiance: self.sky(dir), distance: f32::INFINITY },
            },
            (_, Some(map), _) => match map.trace(origin, dir, DIT_STEPS, DIT_REFINEMENTS) {
                Some(hit) => Incident { radiance: hit.radiance, distance: (hit.point - origin).length() },
                None => Incident { radiance: self.sky(dir), distance: f32::INFINITY },
            },
            _ => Incident { radiance: self.sky(dir), distance: f32::INFINITY },
        }
    }

    /// Whether the real scene, as represented, lets light pass from `origin` to a point
    /// `distance` away along `dir` (a visibility test for the scene's point and spot lights).
    pub fn transmits(&self, query: Query, origin: Vec3, dir: Vec3, distance: f32) -> bool {
        // a point light has no extent: the thinnest cone the volume resolves
        let hit = self.incident(query, origin, dir, 0.0);
        !(hit.distance < distance * 0.98)
    }

    /// Where a query from the real surface at `point` (unit `normal`) starts: just off the
    /// surface, and for VCT a voxel and a half out, past the voxels the surface itself filled
    /// (the usual offset of cone tracing).
    pub fn surface_origin(&self, query: Query, point: Vec3, normal: Vec3) -> Vec3 {
        match (query, &self.voxels) {
            (Query::Vct, Some(voxels)) => point + normal * (1.5 * voxels.voxel),
            _ => point + normal * 1e-3,
        }
    }

    /// The nearest opaque voxel of the objects' solid volumes along a ray leaving the object's
    /// surface at `origin` (geometric normal `normal`, on the side the ray leaves by), past the
    /// voxels that surface fills: the ray starts a voxel diagonal off the surface and half a
    /// diagonal along itself (the usual offsets of cone tracing), so that a ray grazing a face
    /// cut at an angle by the grid is not stopped by the face's own voxels.
    pub fn solid_hit(&self, origin: Vec3, normal: Vec3, dir: Vec3) -> Option<SolidHit> {
        self.solids
            .iter()
            .filter_map(|v| {
                let diagonal = v.voxel.length();
                v.march(origin + normal * diagonal, dir, 0.5 * diagonal, f32::INFINITY)
            })
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }

    /// Bytes held by the representations.
    pub fn bytes(&self) -> usize {
        self.impostors.iter().map(|m| m.bytes()).sum::<usize>()
            + self.voxels.as_ref().map_or(0, |v| v.bytes())
            + self.solids.iter().map(|v| v.bytes()).sum::<usize>()
    }
}
