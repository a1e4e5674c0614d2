//! Tidy checks of the source tree (as rust-analyzer's `tidy` test): every Rust module opens
//! with a `//!` doc saying what it holds, and every crate and module appears in
//! ARCHITECTURE.md's code map, so the map cannot drift from the tree. (The WGSL shaders are
//! found by walking their folder and validated by naga in `mrstudy-renderer`'s
//! `gpu::tests::every_shader_parses_and_validates_with_naga`.)

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The workspace's members (folders, `.` for the binary) and their package names, read from the
/// Cargo.toml files, so a new crate is checked without editing this test.
fn crates() -> Vec<(String, String)> {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let line = manifest.lines().find(|line| line.trim_start().starts_with("members")).expect("a members line");
    let members: Vec<String> =
        line.split('"').enumerate().filter(|(index, _)| index % 2 == 1).map(|(_, member)| member.to_string()).collect();
    assert!(members.len() >= 4, "found only {members:?} in the workspace");
    members
        .into_iter()
        .map(|member| {
            let manifest = std::fs::read_to_string(root().join(&member).join("Cargo.toml")).unwrap();
            let name = manifest
                .lines()
                .find_map(|line| line.strip_prefix("name = \""))
                .and_then(|rest| rest.strip_suffix('"'))
                .expect("a package name")
                .to_string();
            (member, name)
        })
        .collect()
}

/// Every `.rs` file under the crates' `src/` folders.
fn sources() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|extension| extension == "rs") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    for (member, _) in crates() {
        walk(&root().join(member).join("src"), &mut out);
    }
    out.sort();
    assert!(out.len() > 50, "found only {} source files", out.len());
    out
}

fn relative(path: &Path) -> String {
    path.strip_prefix(root()).unwrap().display().to_string()
}

#[test]
fn every_module_opens_with_a_module_doc() {
    let missing: Vec<String> = sources()
        .into_iter()
        .filter(|path| {
            let text = std::fs::read_to_string(path).unwrap();
            !text.trim_start().starts_with("//!")
        })
        .map(|path| relative(&path))
        .collect();
    assert!(missing.is_empty(), "these modules do not open with a `//!` doc: {missing:?}");
}

#[test]
fn every_crate_and_module_is_in_the_code_map() {
    let map = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    for (_, krate) in crates() {
        assert!(map.contains(&format!("`{krate}`")), "ARCHITECTURE.md does not name the crate `{krate}`");
    }
    let mut missing = Vec::new();
    for path in sources() {
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        // A folder module is named by its folder; crate roots and test files by their crate.
        let name = if stem == "mod" {
            path.parent().unwrap().file_name().unwrap().to_string_lossy().to_string()
        } else {
            stem
        };
        if ["lib", "main", "tests"].contains(&name.as_str()) {
            continue;
        }
        let named = map.contains(&format!("`{name}`"))
            || map.contains(&format!("::{name}`"))
            || map.contains(&format!("`{name}/"))
            || map.contains(&format!("{name}.rs"));
        if !named {
            missing.push(relative(&path));
        }
    }
    assert!(missing.is_empty(), "ARCHITECTURE.md's code map does not name these modules: {missing:?}");
}
