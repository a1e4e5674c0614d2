//! The scene as the GPU sees it: one non-indexed triangle list (real objects first, then
//! virtual ones, so either subset is one draw range) and a material table. Real objects use
//! their proxy (the model the renderer believes in); spheres are tessellated. Materials keep
//! the Blinn–Phong parameters of [`crate::material`] and the procedural patterns (wood, checker,
//! stripes, evaluated in the shader exactly as on the CPU); an image texture is replaced by its
//! mean colour (the built-in scenes use none).

use crate::geometry::{Primitive, Triangle};
use crate::material::{DeltaBsdf, Material, Texture};
use crate::scene::{Role, Scene};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// One vertex: position, shading normal, texture coordinate, material index, role (0 real, 1 virtual).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub material: u32,
    pub role: u32,
}

/// One material (std430 layout, 64 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuMaterial {
    /// Diffuse albedo kd; w: pattern kind (0 none, 1 wood, 2 checker, 3 stripes).
    pub albedo: [f32; 4],
    /// Pattern colour a; w: pattern scale.
    pub pattern_a: [f32; 4],
    /// Pattern colour b; w: Blinn–Phong exponent.
    pub pattern_b: [f32; 4],
    /// x: specular ks (grey: the mean of the channels); yzw: emitted radiance.
    pub specular_emission: [f32; 4],
}

/// A mirror or glass object (thesis 5.3): its vertex range in [`GpuMesh::vertices`], its
/// bounding sphere (the centre of its impostor) and its delta BSDF.
#[derive(Clone, Debug)]
pub struct SpecularObject {
    pub name: String,
    pub real: bool,
    pub range: std::ops::Range<u32>,
    pub centre: Vec3,
    pub radius: f32,
    pub material: u32,
    pub delta: DeltaBsdf,
}

pub struct GpuMesh {
    pub vertices: Vec<GpuVertex>,
    /// Vertices `0..real_count` are real, the rest virtual.
    pub real_count: u32,
    pub materials: Vec<GpuMaterial>,
    /// Centre and radius of the bounding sphere of all geometry.
    pub bounds_centre: Vec3,
    pub bounds_radius: f32,
    /// The same for the virtual geometry alone (`None` without virtual objects).
    pub virtual_bounds: Option<(Vec3, f32)>,
    /// The mirrors and glass objects, real and virtual (empty in a scene without them). Their
    /// materials have zero albedo here: they reflect no diffuse light and make no VPLs.
    pub specular: Vec<SpecularObject>,
}

fn bounding_sphere(vertices: &[GpuVertex]) -> Option<(Vec3, f32)> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for v in vertices {
        lo = lo.min(Vec3::from_array(v.position));
        hi = hi.max(Vec3::from_array(v.position));
    }
    if vertices.is_empty() { None } else { Some(((lo + hi) * 0.5, ((hi - lo) * 0.5).length().max(1e-3))) }
}

impl GpuMesh {
    pub fn virtual_count(&self) -> u32 {
        self.vertices.len() as u32 - self.real_count
    }

    /// Every vertex's position with its role in w (0 real, 1 virtual): three per triangle, as
    /// the ISM and multiple-bounce shaders read them.
    pub fn positions_with_role(&self) -> Vec<[f32; 4]> {
        self.vertices.iter().map(|v| [v.position[0], v.position[1], v.position[2], v.role as f32]).collect()
    }
}

fn push_triangle(out: &mut Vec<GpuVertex>, tri: &Triangle, material: u32, role: u32) {
    let ng = tri.geometric_normal();
    for k in 0..3 {
        let n = tri.n.map(|n| n[k]).unwrap_or(ng);
        out.push(GpuVertex {
            position: tri.p[k].to_array(),
            normal: n.to_array(),
            uv: tri.uv[k].to_array(),
            material,
            role,
        });
    }
}

fn sphere_triangles(centre: Vec3, radius: f32, segments: u32) -> Vec<Triangle> {
    let (n_phi, n_theta) = (segments.max(8), (segments / 2).max(4));
    let point = |i: u32, j: u32| {
        let phi = 2.0 * PI * i as f32 / n_phi as f32;
        let theta = PI * j as f32 / n_theta as f32;
        let n = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
        // the CPU tracer's sphere uv: u = 0.5 + atan2(z, x) / 2π, v = acos(y) / π
        (centre + n * radius, n, Vec2::new(0.5 + n.z.atan2(n.x) / (2.0 * PI), theta / PI))
    };
    let mut tris = Vec::new();
    for j in 0..n_theta {
        for i in 0..n_phi {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            for (x, y, z) in [(a, c, b), (a, d, c)] {
                let tri = Triangle { p: [x.0, y.0, z.0], n: Some([x.1, y.1, z.1]), uv: [x.2, y.2, z.2] };
                if tri.area() > 0.0 {
                    tris.push(tri);
                }
            }
        }
    }
    tris
}

fn gpu_material(m: &Material) -> GpuMaterial {
    if m.delta.is_some() {
        // a mirror or glass has no diffuse or glossy lobe: the specular passes shade it
        return GpuMaterial {
            albedo: [0.0; 4],
            pattern_a: [0.0; 4],
            pattern_b: [0.0, 0.0, 0.0, 1.0],
            specular_emission: [0.0; 4],
        };
    }
    let ks = (m.specular.x + m.specular.y + m.specular.z) / 3.0;
    let (kind, a, b, scale, albedo) = match &m.texture {
        None => (0.0, Vec3::ZERO, Vec3::ZERO, 0.0, m.albedo),
        Some(Texture::Wood { light, dark, rings }) => (1.0, *light, *dark, *rings, m.albedo),
        Some(Texture::Checker { a, b, squares }) => (2.0, *a, *b, *squares, m.albedo),
        Some(Texture::Stripes { a, b, count }) => (3.0, *a, *b, *count, m.albedo),
        Some(Texture::Image(img)) => (0.0, Vec3::ZERO, Vec3::ZERO, 0.0, m.albedo * img.mean()),
    };
    GpuMaterial {
        albedo: [albedo.x, albedo.y, albedo.z, kind],
        pattern_a: [a.x, a.y, a.z, scale],
        pattern_b: [b.x, b.y, b.z, m.exponent],
        specular_emission: [ks, m.emission.x, m.emission.y, m.emission.z],
    }
}

/// Builds the GPU mesh of a scene.
pub fn build(scene: &Scene) -> GpuMesh {
    let mut real = Vec::new();
    let mut virt = Vec::new();
    // ranges within each role's list; the virtual ones move behind the real vertices below
    let mut specular = Vec::new();
    for object in &scene.objects {
        let (prims, material) = match (&object.proxy, object.role) {
            (Some((prims, material)), Role::Real) => (prims, *material),
            _ => (&object.prims, object.material),
        };
        let (out, role) = if object.role == Role::Real { (&mut real, 0) } else { (&mut virt, 1) };
        let start = out.len() as u32;
        for prim in prims {
            match prim {
                Primitive::Triangle(tri) => push_triangle(out, tri, material as u32, role),
                Primitive::Sphere { center, radius } => {
                    for tri in sphere_triangles(*center, *radius, 32) {
                        push_triangle(out, &tri, material as u32, role);
                    }
                }
            }
        }
        if let Some(delta) = scene.materials[material].delta
            && let Some((centre, radius)) = bounding_sphere(&out[start as usize..])
        {
            specular.push(SpecularObject {
                name: object.name.clone(),
                real: role == 0,
                range: start..out.len() as u32,
                centre,
                radius,
                material: material as u32,
                delta,
            });
        }
    }
    let real_count = real.len() as u32;
    let virtual_bounds = bounding_sphere(&virt);
    for object in specular.iter_mut().filter(|o| !o.real) {
        object.range = object.range.start + real_count..object.range.end + real_count;
    }
    real.extend(virt);
    let (bounds_centre, bounds_radius) = bounding_sphere(&real).unwrap_or((Vec3::ZERO, 1.0));
    GpuMesh {
        virtual_bounds,
        specular,
        vertices: real,
        real_count,
        materials: scene.materials.iter().map(gpu_material).collect(),
        bounds_centre,
        bounds_radius,
    }
}

/// What [`build`] reads of a scene, as it was when its mesh was built: per object its name,
/// role and the primitives and material it draws (a real object's proxy), and each material's
/// GPU form and delta BSDF.
struct MeshSource {
    objects: Vec<(String, Role, usize, Vec<Primitive>)>,
    materials: Vec<(GpuMaterial, Option<DeltaBsdf>)>,
}

/// The primitives and material an object is drawn with (a real object's proxy where it has one).
fn drawn(object: &crate::scene::SceneObject) -> (&[Primitive], usize) {
    match (&object.proxy, object.role) {
        (Some((prims, material)), Role::Real) => (prims, *material),
        _ => (&object.prims, object.material),
    }
}

/// Whether two primitives have the same numbers, bit for bit (then they make the same vertices).
fn same_prim(a: &Primitive, b: &Primitive) -> bool {
    let bits3 = |v: &[Vec3; 3]| v.map(|p| p.to_array().map(f32::to_bits));
    let bits2 = |v: &[Vec2; 3]| v.map(|p| p.to_array().map(f32::to_bits));
    match (a, b) {
        (Primitive::Triangle(s), Primitive::Triangle(t)) => {
            bits3(&s.p) == bits3(&t.p)
                && bits2(&s.uv) == bits2(&t.uv)
                && s.n.as_ref().map(bits3) == t.n.as_ref().map(bits3)
        }
        (Primitive::Sphere { center: c, radius: r }, Primitive::Sphere { center: d, radius: q }) => {
            c.to_array().map(f32::to_bits) == d.to_array().map(f32::to_bits) && r.to_bits() == q.to_bits()
        }
        _ => false,
    }
}

impl MeshSource {
    fn of(scene: &Scene) -> MeshSource {
        MeshSource {
            objects: scene
                .objects
                .iter()
                .map(|o| {
                    let (prims, material) = drawn(o);
                    (o.name.clone(), o.role, material, prims.to_vec())
                })
                .collect(),
            materials: scene.materials.iter().map(|m| (gpu_material(m), m.delta)).collect(),
        }
    }

    /// Whether `scene` would build the same mesh: the same objects, primitives (bit for bit)
    /// and materials.
    fn matches(&self, scene: &Scene) -> bool {
        self.objects.len() == scene.objects.len()
            && self.materials.len() == scene.materials.len()
            && self.materials.iter().zip(&scene.materials).all(|((gpu, delta), m)| {
                bytemuck::bytes_of(gpu) == bytemuck::bytes_of(&gpu_material(m)) && *delta == m.delta
            })
            && self.objects.iter().zip(&scene.objects).all(|((name, role, material, prims), o)| {
                let (drawn_prims, drawn_material) = drawn(o);
                name == &o.name
                    && *role == o.role
                    && *material == drawn_material
                    && prims.len() == drawn_prims.len()
                    && prims.iter().zip(drawn_prims).all(|(a, b)| same_prim(a, b))
            })
    }
}

/// The last scene's mesh, kept from frame to frame: built again only when the scene's objects or
/// materials changed (a live frame's scene is the same but for the moved object).
#[derive(Default)]
pub struct MeshCache(std::sync::Mutex<Option<(MeshSource, std::sync::Arc<GpuMesh>)>>);

impl MeshCache {
    /// `scene`'s mesh: the kept one when `scene` matches what it was built from, else built.
    pub fn get(&self, scene: &Scene) -> std::sync::Arc<GpuMesh> {
        let mut kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((source, mesh)) = kept.as_ref()
            && source.matches(scene)
        {
            return mesh.clone();
        }
        let mesh = std::sync::Arc::new(build(scene));
        *kept = Some((MeshSource::of(scene), mesh.clone()));
        mesh
    }
}

/// A value made from the scene's mesh — its buffers on the GPU — kept while the mesh cache hands
/// out the same mesh ([`MeshCache::get`]: the same `Arc`, built once and never changed, which
/// the kept one holds), so a frame whose geometry stayed neither makes it again nor compares its
/// bytes with the resident copies' (the glass figure's vertices, the bounces' triangles and CDF:
/// 1.2 ms a frame at the thesis setting on these 2 cores).
pub(super) struct PerMesh<T>(std::sync::Mutex<Option<(std::sync::Arc<GpuMesh>, T)>>);

impl<T> Default for PerMesh<T> {
    fn default() -> Self {
        PerMesh(std::sync::Mutex::new(None))
    }
}

impl<T: Clone> PerMesh<T> {
    /// The value kept for `mesh`, or the one `make` makes from it (the old one let go first, so
    /// that the resident buffers it held can be rewritten in place: [`super::context::GpuContext::resident`]).
    pub(super) fn get(&self, mesh: &std::sync::Arc<GpuMesh>, make: impl FnOnce(&GpuMesh) -> T) -> T {
        let mut kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((of, value)) = kept.as_ref()
            && std::sync::Arc::ptr_eq(of, mesh)
        {
            return value.clone();
        }
        *kept = None;
        let value = make(mesh);
        *kept = Some((mesh.clone(), value.clone()));
        value
    }
}
