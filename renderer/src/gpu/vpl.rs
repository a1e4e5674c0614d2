//! VPL creation from reflective shadow maps (thesis 5.2.7, "The Spot Light Source"), of spot
//! lights and of directions of the environment light (orthographic RSMs; the environment is real,
//! and a texel reflects albedo · E · its area across the beam). A real spot
//! has two RSMs, real-only and virtual-only; a virtual spot too (its real-only map is then only
//! used where no virtual surface is in front). Each RSM texel is a candidate VPL carrying the
//! diffusely reflected flux albedo · I(ω) · dω of the light that reaches it; the flags follow
//! section 5.2.3 and eqs. 5.9–5.10:
//!
//! - a real surface with nothing virtual in front: path flag r = r(pl), ir = 0;
//! - a real surface behind a virtual one, for a real light: r = 1, ir = 1 (VPL 3 of Figure 5.7:
//!   it exists only in the real-only solution); for a virtual light it does not exist;
//! - a virtual surface in front (or alone): r = 0, ir = 0.
//!
//! The VPLs are drawn from all candidates of all spot lights together, in proportion to their
//! flux (stratified inversion of the CDF, deterministic), and each carries flux / (N · p): the
//! budget is thereby split over the lights by flux — the thesis's third distribution mode — and
//! over the two RSMs by the flux they hold, with the compensation built in. The RSMs are read
//! back and sampled on the CPU (a GPU sampler is future work).

use crate::light::SpotLight;
use crate::math::luminance;
use glam::Vec3;

/// One VPL: matches `Vpl` in shade.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuVpl {
    /// xyz; w: the path flag (1: light and surface real).
    pub position: [f32; 4],
    /// xyz; w: ir(VPL) (1: only the real-only solution).
    pub normal: [f32; 4],
    /// rgb: reflected flux (W); w: 1 for a reflected or refracted VPL of a caustic (Figure
    /// 5.23), 0 otherwise (the shaders read only rgb).
    pub flux: [f32; 4],
}

/// One RSM texel: position (w: flag + 4·material, 0 empty), normal, albedo, distance to the light.
pub type RsmTexel = ([f32; 4], [f32; 4], [f32; 4], f32);

/// The read-back RSMs of one spot light.
pub struct RsmTexels {
    pub size: u32,
    /// Half-width of the light's image plane at unit distance (tan of half the field of view).
    pub tan_half_fov: f32,
    /// Per texel of the real-only map.
    pub real: Vec<RsmTexel>,
    /// The same for the virtual-only map.
    pub virt: Vec<RsmTexel>,
}

/// The primary light an RSM was rendered from.
#[derive(Clone, Copy, Debug)]
pub enum RsmLight<'a> {
    /// A spot light (perspective RSM).
    Spot(&'a SpotLight),
    /// A direction of the environment light (orthographic RSM): irradiance on a surface facing
    /// it (W/m²) and the area of one texel across the beam (m²). The environment is real.
    Directional { irradiance: Vec3, texel_area: f32 },
}

impl RsmLight<'_> {
    fn real(&self) -> bool {
        match self {
            RsmLight::Spot(light) => light.real,
            RsmLight::Directional { .. } => true,
        }
    }
}

struct Candidate {
    vpl: GpuVpl,
    weight: f32,
}

impl Candidate {
    /// A VPL as a candidate weighted by its flux's luminance; `None` without usable flux.
    fn of(vpl: &GpuVpl) -> Option<Candidate> {
        let weight = luminance(Vec3::new(vpl.flux[0], vpl.flux[1], vpl.flux[2]));
        (weight > 0.0 && weight.is_finite()).then_some(Candidate { vpl: *vpl, weight })
    }
}

fn candidate(
    light: &RsmLight,
    rsm: &RsmTexels,
    idx: usize,
    texel: &RsmTexel,
    path_flag: f32,
    ir: f32,
) -> Option<Candidate> {
    let (position, normal, albedo, _) = texel;
    let p = Vec3::new(position[0], position[1], position[2]);
    let light = match light {
        RsmLight::Spot(light) => *light,
        RsmLight::Directional { irradiance, texel_area } => {
            // the texel's footprint across the beam receives E · A; a diffuse surface reflects
            // albedo times that, whatever its tilt
            let flux = Vec3::new(albedo[0], albedo[1], albedo[2]) * *irradiance * *texel_area;
            let weight = luminance(flux);
            if weight <= 0.0 || !weight.is_finite() {
                return None;
            }
            return Some(Candidate {
                vpl: GpuVpl {
                    position: [p.x, p.y, p.z, path_flag],
                    normal: [normal[0], normal[1], normal[2], ir],
                    flux: [flux.x, flux.y, flux.z, 0.0],
                },
                weight,
            });
        }
    };
    let to_surface = p - light.position;
    let dist = to_surface.length();
    if dist <= 0.0 {
        return None;
    }
    let intensity = light.intensity_towards(to_surface / dist);
    let d_omega = texel_solid_angle(idx as u32 % rsm.size, idx as u32 / rsm.size, rsm.size, rsm.tan_half_fov);
    let flux = Vec3::new(albedo[0], albedo[1], albedo[2]) * intensity * d_omega;
    let weight = luminance(flux);
    if weight <= 0.0 || !weight.is_finite() {
        return None;
    }
    Some(Candidate {
        vpl: GpuVpl {
            position: [p.x, p.y, p.z, path_flag],
            normal: [normal[0], normal[1], normal[2], ir],
            flux: [flux.x, flux.y, flux.z, 0.0],
        },
        weight,
    })
}

/// The solid angle of texel (ix, iy) of a square perspective map of `size`² whose half field
/// of view has tangent `tan_half`: the texel's area on the unit image plane / (1 + x² + y²)^{3/2}.
pub fn texel_solid_angle(ix: u32, iy: u32, size: u32, tan_half: f32) -> f32 {
    let x = (2.0 * (ix as f32 + 0.5) / size as f32 - 1.0) * tan_half;
    let y = (2.0 * (iy as f32 + 0.5) / size as f32 - 1.0) * tan_half;
    (2.0 * tan_half / size as f32).powi(2) / (1.0 + x * x + y * y).powf(1.5)
}

/// Draws `count` VPLs from the RSMs of the given lights (spot lights and environment
/// directions).
pub fn create(lights: &[(RsmLight, RsmTexels)], count: u32) -> Vec<GpuVpl> {
    create_with(lights, &[], count)
}

/// [`create`], with further candidate VPLs drawn together with the RSMs' in proportion to
/// their flux: the reflected and refracted VPLs of caustics.
pub fn create_with(lights: &[(RsmLight, RsmTexels)], extra: &[GpuVpl], count: u32) -> Vec<GpuVpl> {
    Candidates::new(lights, extra).draw(count)
}

/// The candidate VPLs of [`create_with`] — `extra` first, then every light's RSM texels in
/// order — each weighted by its flux's luminance: made once, drawn from as often as needed (a
/// frame with more bounces draws the first bounce's VPLs twice, as a pilot and for its share of
/// the budget). The lights' maps are gone through on all threads and joined in order, so the
/// candidates, and what is drawn from them, do not depend on the thread count.
pub struct Candidates(Vec<Candidate>);

impl Candidates {
    pub fn new(lights: &[(RsmLight, RsmTexels)], extra: &[GpuVpl]) -> Candidates {
        use rayon::prelude::*;
        let mut candidates: Vec<Candidate> = extra.iter().filter_map(Candidate::of).collect();
        let per_light: Vec<Vec<Candidate>> =
            lights.par_iter().map(|(light, rsm)| light_candidates(light, rsm)).collect();
        candidates.reserve(per_light.iter().map(Vec::len).sum());
        for found in per_light {
            candidates.extend(found);
        }
        Candidates(candidates)
    }

    /// `count` VPLs drawn in proportion to the candidates' flux (see `draw`).
    pub fn draw(&self, count: u32) -> Vec<GpuVpl> {
        draw(&self.0, count)
    }
}

/// The candidates of one light's RSM texels, in texel order.
fn light_candidates(light: &RsmLight, rsm: &RsmTexels) -> Vec<Candidate> {
    let r_pl = if light.real() { 1.0 } else { 0.0 };
    let mut candidates = Vec::new();
    for idx in 0..rsm.real.len() {
        let real = &rsm.real[idx];
        let virt = &rsm.virt[idx];
        let has_real = real.0[3] > 0.5;
        let has_virt = virt.0[3] > 0.5;
        let virtual_in_front = has_virt && (!has_real || virt.3 < real.3);
        let found = if virtual_in_front {
            let shadowed_real =
                if has_real && light.real() { candidate(light, rsm, idx, real, 1.0, 1.0) } else { None };
            [candidate(light, rsm, idx, virt, 0.0, 0.0), shadowed_real]
        } else if has_real {
            [candidate(light, rsm, idx, real, r_pl, 0.0), None]
        } else {
            [None, None]
        };
        candidates.extend(found.into_iter().flatten());
    }
    candidates
}

/// Draws `count` VPLs from weighted candidates: stratified inversion of the weights' CDF, each
/// drawn VPL carrying flux / (count · p) (deterministic).
fn draw(candidates: &[Candidate], count: u32) -> Vec<GpuVpl> {
    let weights: Vec<f64> = candidates.iter().map(|c| c.weight as f64).collect();
    stratify(&weights, count)
        .into_iter()
        .map(|(i, p)| {
            let scale = (1.0 / (count as f64 * p)) as f32;
            let mut vpl = candidates[i].vpl;
            vpl.flux = [vpl.flux[0] * scale, vpl.flux[1] * scale, vpl.flux[2] * scale, vpl.flux[3]];
            vpl
        })
        .collect()
}

/// Stratified inversion of the CDF of non-negative `weights`: for each stratum (k + 0.5) / count,
/// the index whose CDF interval holds it and that index's probability, in index order; empty
/// when the weights sum to zero or `count` is 0. VPL creation and the multiple-bounce source's
/// slots draw with it.
pub fn stratify(weights: &[f64], count: u32) -> Vec<(usize, f64)> {
    let total: f64 = weights.iter().sum();
    if weights.is_empty() || total <= 0.0 || count == 0 {
        return Vec::new();
    }
    let mut drawn = Vec::with_capacity(count as usize);
    let mut cumulative = 0.0f64;
    let mut next = 0usize;
    for (i, w) in weights.iter().enumerate() {
        let p = w / total;
        cumulative += p;
        while next < count as usize && (next as f64 + 0.5) / count as f64 <= cumulative {
            drawn.push((i, p));
            next += 1;
        }
    }
    drawn
}

/// Draws `count` VPLs from a larger set in proportion to their flux, keeping its total flux in
/// expectation (each carries total / count in luminance): how a bounce's pilot VPLs shrink to
/// the bounce's share of the budget.
pub fn resample(vpls: &[GpuVpl], count: u32) -> Vec<GpuVpl> {
    let candidates: Vec<Candidate> = vpls.iter().filter_map(Candidate::of).collect();
    draw(&candidates, count)
}

/// Total luminance flux of a set of VPLs.
pub fn luminance_flux(vpls: &[GpuVpl]) -> f64 {
    vpls.iter().map(|v| luminance(Vec3::new(v.flux[0], v.flux[1], v.flux[2])) as f64).filter(|w| w.is_finite()).sum()
}

/// Splits `budget` VPLs over light sources in proportion to their flux (the thesis's third
/// distribution mode), by largest remainder; a source with flux gets at least one VPL while the
/// budget lasts.
pub fn split_budget(budget: u32, fluxes: &[f64]) -> Vec<u32> {
    let valid: Vec<f64> = fluxes.iter().map(|f| if f.is_finite() && *f > 0.0 { *f } else { 0.0 }).collect();
    let total: f64 = valid.iter().sum();
    if total <= 0.0 {
        return vec![0; fluxes.len()];
    }
    let exact: Vec<f64> = valid.iter().map(|f| budget as f64 * f / total).collect();
    let mut counts: Vec<u32> = exact.iter().map(|e| e.floor() as u32).collect();
    let mut left = budget - counts.iter().sum::<u32>();
    // first, every source with flux and no VPL yet; then the largest remainders
    let mut order: Vec<usize> = (0..exact.len()).filter(|&i| valid[i] > 0.0).collect();
    order.sort_by(|&a, &b| {
        (counts[a] > 0)
            .cmp(&(counts[b] > 0))
            .then((exact[b] - exact[b].floor()).total_cmp(&(exact[a] - exact[a].floor())))
    });
    for i in order {
        if left == 0 {
            break;
        }
        counts[i] += 1;
        left -= 1;
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spot(real: bool) -> SpotLight {
        SpotLight {
            name: "s".into(),
            position: Vec3::new(0.0, 1.0, 0.0),
            direction: Vec3::NEG_Y,
            cos_inner: 0.5,
            cos_outer: 0.4,
            intensity: Vec3::ONE,
            real,
        }
    }

    fn texel(y: f32, flag: f32, albedo: f32) -> RsmTexel {
        ([0.0, y, 0.0, flag], [0.0, 1.0, 0.0, 1.0], [albedo, albedo, albedo, 0.0], 1.0 - y)
    }

    const EMPTY: RsmTexel = ([0.0; 4], [0.0; 4], [0.0; 4], 1e30);

    #[test]
    fn flux_is_conserved_and_flags_follow_section_5_2_3() {
        // one texel: a real floor with a virtual box in front, under a real light
        let rsm = RsmTexels {
            size: 1,
            tan_half_fov: 0.1,
            real: vec![texel(0.0, 1.0, 0.5)],
            virt: vec![texel(0.5, 2.0, 0.8)],
        };
        let light = spot(true);
        let vpls = create(&[(RsmLight::Spot(&light), rsm)], 64);
        assert_eq!(vpls.len(), 64);
        let (virt, real): (Vec<&GpuVpl>, Vec<&GpuVpl>) = vpls.iter().partition(|v| v.position[3] == 0.0);
        assert!(virt.iter().all(|v| v.normal[3] == 0.0), "a VPL on a virtual surface lights L_rv");
        assert!(real.iter().all(|v| v.normal[3] == 1.0), "a real VPL behind a virtual one lights L_r only");
        // expected flux of each: albedo · I · dω; their sums are preserved by the sampling
        let d_omega = 0.2f32 * 0.2;
        let sum = |vs: &[&GpuVpl]| vs.iter().map(|v| v.flux[0]).sum::<f32>();
        // stratified sampling rounds each candidate's share to whole VPLs: within 1/N
        assert!((sum(&virt) / (0.8 * d_omega) - 1.0).abs() < 2.0 / 64.0, "{}", sum(&virt));
        assert!((sum(&real) / (0.5 * d_omega) - 1.0).abs() < 2.0 / 64.0, "{}", sum(&real));
    }

    #[test]
    fn an_environment_direction_reflects_albedo_times_irradiance_times_texel_area() {
        // two texels: a real floor, and a virtual box in front of the real floor
        let rsm = RsmTexels {
            size: 2,
            tan_half_fov: 0.0,
            real: vec![texel(0.0, 1.0, 0.5), texel(0.0, 1.0, 0.5), EMPTY, EMPTY],
            virt: vec![EMPTY, texel(0.5, 2.0, 0.8), EMPTY, EMPTY],
        };
        let light = RsmLight::Directional { irradiance: Vec3::splat(2.0), texel_area: 0.01 };
        let vpls = create(&[(light, rsm)], 300);
        assert_eq!(vpls.len(), 300);
        let sum = |f: &dyn Fn(&GpuVpl) -> bool| vpls.iter().filter(|v| f(v)).map(|v| v.flux[0] as f64).sum::<f64>();
        // the open floor texel: a real path (r = 1, ir = 0), flux 0.5 · 2 · 0.01
        let open = sum(&|v| v.position[3] == 1.0 && v.normal[3] == 0.0);
        assert!((open / 0.01 - 1.0).abs() < 0.02, "{open}");
        // the virtual box (r = 0) and the real floor behind it, for the real-only solution (ir = 1)
        let virt = sum(&|v| v.position[3] == 0.0);
        let behind = sum(&|v| v.normal[3] == 1.0);
        assert!((virt / 0.016 - 1.0).abs() < 0.02 && (behind / 0.01 - 1.0).abs() < 0.02, "{virt} {behind}");
    }

    #[test]
    fn resampling_keeps_the_flux_and_the_budget_split_follows_it() {
        let vpl = |f: f32| GpuVpl { position: [0.0; 4], normal: [0.0, 1.0, 0.0, 0.0], flux: [f, f, f, 0.0] };
        let set: Vec<GpuVpl> = (1..=40).map(|k| vpl(k as f32)).collect();
        let drawn = resample(&set, 10);
        assert_eq!(drawn.len(), 10);
        assert!((luminance_flux(&drawn) / luminance_flux(&set) - 1.0).abs() < 1e-5);
        assert!(resample(&[vpl(0.0), vpl(f32::NAN)], 4).is_empty());
        assert_eq!(split_budget(256, &[3.0, 1.0]), vec![192, 64]);
        assert_eq!(split_budget(10, &[1.0, 1.0, 1.0]).iter().sum::<u32>(), 10);
        assert_eq!(split_budget(4, &[1000.0, 1.0]), vec![3, 1], "every source with flux gets a VPL");
        assert_eq!(split_budget(8, &[1.0, 0.0, f64::NAN]), vec![8, 0, 0]);
        assert_eq!(split_budget(8, &[0.0]), vec![0]);
    }

    #[test]
    fn virtual_light_gives_no_vpl_behind_virtual_surfaces_and_no_real_path_flag() {
        let rsm = RsmTexels {
            size: 2,
            tan_half_fov: 0.1,
            real: vec![texel(0.0, 1.0, 0.5), texel(0.0, 1.0, 0.5), EMPTY, EMPTY],
            virt: vec![texel(0.5, 2.0, 0.8), EMPTY, EMPTY, EMPTY],
        };
        let light = spot(false);
        let vpls = create(&[(RsmLight::Spot(&light), rsm)], 16);
        assert!(vpls.iter().all(|v| v.position[3] == 0.0 && v.normal[3] == 0.0));
    }
}
