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

/// Files declared only for tests (`#[cfg(test)] mod x;` in their parent), by path.
fn test_only(path: &Path) -> bool {
    let stem = path.file_stem().unwrap().to_string_lossy().to_string();
    if stem == "tests" || stem == "test_support" {
        return true;
    }
    let parent = path.parent().unwrap();
    let declared_in = [parent.join("mod.rs"), parent.join("lib.rs"), parent.with_extension("rs")];
    declared_in.iter().filter_map(|file| std::fs::read_to_string(file).ok()).any(|text| {
        text.contains(&format!("#[cfg(test)]\nmod {stem};")) || text.contains(&format!("#[cfg(test)]\npub mod {stem};"))
    })
}

#[test]
fn no_crate_has_an_import_cycle_between_its_top_level_modules() {
    for (member, krate) in crates() {
        let src = root().join(&member).join("src");
        // top-level module → the top-level modules its code names as `crate::x`
        let mut uses: std::collections::BTreeMap<String, std::collections::BTreeSet<String>> = Default::default();
        for path in sources().into_iter().filter(|path| path.starts_with(&src) && !test_only(path)) {
            let relative = path.strip_prefix(&src).unwrap().to_string_lossy().to_string();
            let top = relative.split('/').next().unwrap().trim_end_matches(".rs").to_string();
            if top == "lib" || top == "main" {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let code = text.split("#[cfg(test)]\nmod tests {").next().unwrap();
            let entry = uses.entry(top.clone()).or_default();
            for line in code.lines().filter(|line| !line.trim_start().starts_with("//")) {
                for (index, _) in line.match_indices("crate::") {
                    let name: String =
                        line[index + 7..].chars().take_while(|c| c.is_ascii_lowercase() || *c == '_').collect();
                    if !name.is_empty() && name != top {
                        entry.insert(name);
                    }
                }
            }
        }
        // a cycle exists iff some module reaches itself
        for start in uses.keys() {
            let mut seen = std::collections::BTreeSet::new();
            let mut stack: Vec<(String, Vec<String>)> = vec![(start.clone(), vec![start.clone()])];
            while let Some((module, trail)) = stack.pop() {
                for next in uses.get(&module).into_iter().flatten() {
                    if next == start {
                        panic!("{krate} has an import cycle: {} → {start}", trail.join(" → "));
                    }
                    if seen.insert(next.clone()) {
                        stack.push((next.clone(), [trail.clone(), vec![next.clone()]].concat()));
                    }
                }
            }
        }
    }
}
