//! Triangle meshes from files: glTF 2.0 (`.gltf`, `.glb`, through the `gltf` crate, node
//! transforms applied) and Wavefront OBJ (through `tobj`). Materials in the files are ignored:
//! the scene file gives the object's material. Positions, normals and texture coordinates are
//! kept.

use crate::error::{RenderError, Result};
use crate::geometry::Triangle;
use glam::{Mat4, Vec2, Vec3};
use std::path::Path;

/// Loads every triangle of a mesh file, in the file's own coordinates.
pub fn load(path: &Path) -> Result<Vec<Triangle>> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    let missing = |reason: String| RenderError::MissingFile { what: "mesh", path: path.to_owned(), reason };
    if !path.exists() {
        return Err(missing("no such file".into()));
    }
    match ext.as_str() {
        "gltf" | "glb" => load_gltf(path).map_err(missing),
        "obj" => load_obj(path).map_err(missing),
        other => Err(missing(format!("unsupported mesh format `.{other}` (expected .gltf, .glb or .obj)"))),
    }
}

fn load_gltf(path: &Path) -> std::result::Result<Vec<Triangle>, String> {
    let (doc, buffers, _images) = gltf::import(path).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    let scene = doc.default_scene().or_else(|| doc.scenes().next()).ok_or("the file has no scene")?;
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let m = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            let nm = glam::Mat3::from_mat4(m).inverse().transpose();
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let pos: Vec<Vec3> = match reader.read_positions() {
                    Some(p) => p.map(|p| m.transform_point3(Vec3::from_array(p))).collect(),
                    None => continue,
                };
                let nrm: Option<Vec<Vec3>> =
                    reader.read_normals().map(|n| n.map(|n| (nm * Vec3::from_array(n)).normalize_or_zero()).collect());
                let uvs: Option<Vec<Vec2>> =
                    reader.read_tex_coords(0).map(|t| t.into_f32().map(|t| Vec2::new(t[0], 1.0 - t[1])).collect());
                let idx: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..pos.len() as u32).collect(),
                };
                for t in idx.chunks_exact(3) {
                    let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
                    if a >= pos.len() || b >= pos.len() || c >= pos.len() {
                        return Err(format!("index out of range in mesh `{}`", mesh.index()));
                    }
                    out.push(Triangle {
                        p: [pos[a], pos[b], pos[c]],
                        n: nrm.as_ref().map(|n| [n[a], n[b], n[c]]),
                        uv: uvs.as_ref().map(|u| [u[a], u[b], u[c]]).unwrap_or([Vec2::ZERO; 3]),
                    });
                }
            }
        }
        for child in node.children() {
            stack.push((child, m));
        }
    }
    Ok(out)
}

fn load_obj(path: &Path) -> std::result::Result<Vec<Triangle>, String> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, _materials) = tobj::load_obj(path, &opts).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for model in models {
        let m = &model.mesh;
        let p = |i: usize| Vec3::new(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
        let has_n = m.normals.len() == m.positions.len();
        let has_uv = m.texcoords.len() / 2 == m.positions.len() / 3;
        for t in m.indices.chunks_exact(3) {
            let i = [t[0] as usize, t[1] as usize, t[2] as usize];
            out.push(Triangle {
                p: i.map(p),
                n: has_n.then(|| i.map(|k| Vec3::new(m.normals[3 * k], m.normals[3 * k + 1], m.normals[3 * k + 2]))),
                uv: if has_uv {
                    i.map(|k| Vec2::new(m.texcoords[2 * k], m.texcoords[2 * k + 1]))
                } else {
                    [Vec2::ZERO; 3]
                },
            });
        }
    }
    Ok(out)
}
