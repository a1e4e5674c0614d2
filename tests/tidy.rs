//! Tidy checks of the source tree (as rust-analyzer's `tidy` test): every Rust module opens
//! with a `//!` doc saying what it holds, and every crate and module appears in
//! ARCHITECTURE.md's code map, so the map cannot drift from the tree; no crate has a cycle
//! between its modules at any depth, no source file is over 900 lines, and every public
//! function has a caller outside tests. (The WGSL shaders are found by walking their folder
//! and validated by naga in `mrstudy-renderer`'s
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

/// The long flags (`--name`) an option line of a `--help` text names, `--help` and `--version`
/// left out.
fn long_flags(help: &str) -> Vec<String> {
    let mut flags = Vec::new();
    for line in help.lines().map(str::trim_start).filter(|line| line.starts_with('-')) {
        // `-s, --name <VALUE>`: the flag is the first word that starts with two dashes
        let Some(word) = line.split([' ', ',', '=']).find(|word| word.starts_with("--")) else { continue };
        let flag: String = word.chars().take_while(|c| *c == '-' || c.is_ascii_alphanumeric()).collect();
        if flag.len() > 2 && flag != "--help" && flag != "--version" {
            flags.push(flag);
        }
    }
    flags
}

/// The subcommands `mrstudy --help` lists.
fn subcommands(help: &str) -> Vec<String> {
    let section = help.split("Commands:").nth(1).expect("a Commands: section in mrstudy --help");
    let section = section.split("\n\n").next().unwrap();
    section
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_string)
        .collect()
}

fn help_of(args: &[&str]) -> String {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_mrstudy")).args(args).arg("--help").output().unwrap();
    assert!(output.status.success(), "mrstudy {args:?} --help failed: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap()
}

/// Whether `text` names `flag` as a whole word (`--plot` does not count as `--plot-dir`).
fn names_flag(text: &str, flag: &str) -> bool {
    text.match_indices(flag).any(|(index, _)| {
        let next = text[index + flag.len()..].chars().next();
        !next.is_some_and(|c| c == '-' || c.is_ascii_alphanumeric())
    })
}

#[test]
fn every_long_flag_of_the_command_line_is_in_the_design() {
    let design = std::fs::read_to_string(root().join("docs/design.md")).unwrap();
    let top = help_of(&[]);
    let commands = subcommands(&top);
    assert!(commands.len() >= 8, "found only {commands:?} in mrstudy --help");
    let mut missing = Vec::new();
    for command in &commands {
        let flags = long_flags(&help_of(&[command]));
        assert!(!flags.is_empty() || command == "power", "mrstudy {command} --help lists no flag");
        for flag in flags {
            if !names_flag(&design, &flag) {
                missing.push(format!("mrstudy {command} {flag}"));
            }
        }
    }
    assert!(missing.is_empty(), "docs/design.md does not name these flags: {missing:?}");
}

/// The routes the server's router serves: every `.route("…"` of `server/src` outside its test
/// modules (the router is built from each area's `router()`, so the strings are the routes).
fn routes() -> Vec<String> {
    fn walk(dir: &Path, out: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|extension| extension == "rs") && !test_only(&path) {
                let text = std::fs::read_to_string(&path).unwrap();
                let code = text.split("#[cfg(test)]").next().unwrap();
                for (index, _) in code.match_indices(".route(\"") {
                    let rest = &code[index + 8..];
                    out.push(rest[..rest.find('"').unwrap()].to_string());
                }
            }
        }
    }
    let mut out = Vec::new();
    walk(&root().join("server/src"), &mut out);
    out.sort();
    out.dedup();
    out
}

#[test]
fn every_route_of_the_router_is_in_the_design() {
    let design = std::fs::read_to_string(root().join("docs/design.md")).unwrap();
    let routes = routes();
    assert!(routes.len() >= 25, "found only {} routes in server/src: {routes:?}", routes.len());
    assert!(routes.iter().any(|route| route == "/api/participants/{id}/responses"), "{routes:?}");
    let missing: Vec<&String> = routes
        .iter()
        .filter(|route| !design.contains(&format!("`{route}`")) && !design.contains(&format!(" {route}`")))
        .collect();
    assert!(missing.is_empty(), "docs/design.md does not name these routes: {missing:?}");
}

/// Every relative link `](target#fragment)` of a markdown text as (target, fragment); the target
/// is empty for a link within the page.
fn relative_links(text: &str) -> Vec<(String, Option<String>)> {
    text.match_indices("](")
        .filter_map(|(index, _)| {
            let rest = &text[index + 2..];
            let link = rest[..rest.find(')')?].trim();
            let (target, fragment) = match link.split_once('#') {
                Some((target, fragment)) => (target, Some(fragment.to_string())),
                None => (link, None),
            };
            let external = link.is_empty() || target.contains("://") || target.starts_with("mailto:");
            (!external).then(|| (target.to_string(), fragment))
        })
        .collect()
}

/// The anchors GitHub gives a markdown page's headings: lower case, letters, digits, `-` and `_`
/// kept, spaces as `-`, a repeated heading numbered `-1`, `-2`, ….
fn anchors(text: &str) -> Vec<String> {
    let mut anchors: Vec<String> = Vec::new();
    let mut in_code = false;
    for line in text.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
        }
        let Some(heading) = line.strip_prefix('#').filter(|_| !in_code) else { continue };
        let heading = heading.trim_start_matches('#');
        if !heading.starts_with(' ') {
            continue;
        }
        let slug: String = heading
            .trim()
            .to_lowercase()
            .chars()
            .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
            .map(|c| if c == ' ' { '-' } else { c })
            .collect();
        let repeats = anchors.iter().filter(|anchor| **anchor == slug).count();
        anchors.push(if repeats == 0 { slug.clone() } else { format!("{slug}-{repeats}") });
    }
    anchors
}

#[test]
fn every_relative_link_of_the_readme_and_the_docs_resolves_to_a_file_and_heading() {
    let mut pages = vec![root().join("README.md"), root().join("ARCHITECTURE.md")];
    for entry in std::fs::read_dir(root().join("docs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|extension| extension == "md") {
            pages.push(path);
        }
    }
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for (target, fragment) in relative_links(&text) {
            checked += 1;
            let file = if target.is_empty() { page.clone() } else { page.parent().unwrap().join(&target) };
            if !file.exists() {
                broken.push(format!("{}: {target}", relative(page)));
            } else if let Some(fragment) = fragment.filter(|_| file.extension().is_some_and(|e| e == "md"))
                && !anchors(&std::fs::read_to_string(&file).unwrap()).contains(&fragment)
            {
                broken.push(format!("{}: {target}#{fragment} (no such heading)", relative(page)));
            }
        }
    }
    assert!(checked >= 10, "found only {checked} relative links");
    assert!(broken.is_empty(), "these relative links point at nothing: {broken:?}");
}

#[test]
fn the_readme_stays_short() {
    let lines = std::fs::read_to_string(root().join("README.md")).unwrap().lines().count();
    assert!(lines <= 300, "README.md has {lines} lines; move the detail into docs/ and keep it at 300 or fewer");
}

/// `scripts/serve.sh` with a stand-in `cargo` first on the PATH (it records its arguments), so
/// the test builds nothing; `probe` is where the script looks for Mesa's Vulkan drivers.
fn run_serve_script(probe: &Path, dir: &Path) -> (std::process::Output, Option<String>) {
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let record = dir.join("cargo-args");
    let fake = bin.join("cargo");
    std::fs::write(
        &fake,
        format!("#!/bin/sh\necho \"$@ XDG_RUNTIME_DIR=$XDG_RUNTIME_DIR\" > '{}'\n", record.display()),
    )
    .unwrap();
    std::process::Command::new("chmod").arg("+x").arg(&fake).status().unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let output = std::process::Command::new("bash")
        .arg(root().join("scripts/serve.sh"))
        .args(["--addr", "127.0.0.1:0"])
        .env("PATH", path)
        .env("MRSTUDY_VULKAN_PROBE", probe)
        .env("MRSTUDY_NO_INSTALL", "1")
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("MRSTUDY_ADAPTER")
        .env("TMPDIR", dir)
        .output()
        .unwrap();
    (output, std::fs::read_to_string(record).ok())
}

#[test]
fn the_serve_script_names_the_missing_package_and_stops() {
    let dir = tempfile::tempdir().unwrap();
    let (output, cargo) = run_serve_script(&dir.path().join("no-such-icd.json"), dir.path());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "serve.sh went on without the drivers: {stderr}");
    assert!(cargo.is_none(), "serve.sh ran cargo without the drivers: {cargo:?}");
    assert!(stderr.contains("apt-get install mesa-vulkan-drivers"), "no install sentence: {stderr}");
    assert!(stderr.contains("no-such-icd.json"), "the sentence does not name the probe: {stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "more than one sentence: {stderr}");
}

#[test]
fn the_serve_script_serves_when_the_drivers_are_there() {
    let dir = tempfile::tempdir().unwrap();
    let probe = dir.path().join("lvp_icd.json");
    std::fs::write(&probe, "{}").unwrap();
    let (output, cargo) = run_serve_script(&probe, dir.path());
    assert!(output.status.success(), "serve.sh failed: {}", String::from_utf8_lossy(&output.stderr));
    let cargo = cargo.expect("serve.sh did not run cargo");
    assert!(cargo.starts_with("run --release --locked -- serve --addr 127.0.0.1:0 "), "cargo ran as {cargo}");
    let runtime = cargo.split("XDG_RUNTIME_DIR=").nth(1).unwrap().trim();
    assert!(runtime.starts_with(&dir.path().display().to_string()), "XDG_RUNTIME_DIR not set: {cargo}");
}

#[test]
fn the_code_map_stays_dense() {
    let map = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let long: Vec<&str> = map.lines().filter(|line| line.chars().count() > 100).collect();
    assert!(long.is_empty(), "ARCHITECTURE.md has lines over 100 columns: {long:?}");
    assert!(map.len() < 15_000, "ARCHITECTURE.md has {} bytes; keep it under 15 KB", map.len());
}

/// A source file's module path inside its crate (`server/src/admin/store.rs` → `admin::store`,
/// a `mod.rs` by its folder, the crate root empty).
fn module_path(src: &Path, path: &Path) -> Vec<String> {
    let relative = path.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = relative.iter().map(|part| part.to_string_lossy().to_string()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// A file's code without its inline `#[cfg(test)] mod tests { … }` (kept last, by the house style).
fn non_test_code(text: &str) -> &str {
    text.split("#[cfg(test)]\nmod tests {").next().unwrap()
}

/// The module paths a line names: `crate::a::b`, `super::a`, `self::a`, each also in a `{…}`
/// group (`use super::{a, b::c}`), as written (not yet resolved).
fn named_paths(line: &str) -> Vec<(String, Vec<String>)> {
    let ident =
        |text: &str| -> String { text.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect() };
    // an identifier chain `a::b::c` at the start of `text`, and what follows it
    fn chain(text: &str, ident: &dyn Fn(&str) -> String) -> (Vec<String>, usize) {
        let mut parts = Vec::new();
        let mut at = 0;
        loop {
            let name = ident(&text[at..]);
            if name.is_empty() {
                break;
            }
            at += name.len();
            parts.push(name);
            if text[at..].starts_with("::") && !text[at + 2..].starts_with('{') {
                at += 2;
            } else {
                break;
            }
        }
        (parts, at)
    }
    let mut found = Vec::new();
    for prefix in ["crate::", "super::", "self::"] {
        for (index, _) in line.match_indices(prefix) {
            if index > 0 && line[..index].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let root = prefix.trim_end_matches("::").to_string();
            let rest = &line[index + prefix.len()..];
            let (parts, at) = chain(rest, &ident);
            let after = &rest[at..];
            if let Some(group) =
                after.strip_prefix("::{").or_else(|| if parts.is_empty() { rest.strip_prefix('{') } else { None })
            {
                let group = group.split('}').next().unwrap_or("");
                for item in group.split(',') {
                    let (more, _) = chain(item.trim(), &ident);
                    found.push((root.clone(), [parts.clone(), more].concat()));
                }
            } else {
                found.push((root, parts));
            }
        }
    }
    found
}

/// Module cycles at any depth: every reference from module A to module B (neither inside the
/// other) becomes an edge between the two children of their deepest common ancestor that hold
/// them; a cycle among some module's children is a cycle (named by its modules, sorted). None
/// is allowed (the renderer's last, gpu::context ↔ gpu::pool, was broken in issue 51).
#[test]
fn no_crate_has_an_import_cycle_between_modules_at_any_depth() {
    const ALLOWED: &[&str] = &[];
    use std::collections::{BTreeMap, BTreeSet};
    let mut cycles = BTreeSet::new();
    for (member, krate) in crates() {
        let src = root().join(&member).join("src");
        let files: Vec<PathBuf> =
            sources().into_iter().filter(|path| path.starts_with(&src) && !test_only(path)).collect();
        let modules: BTreeSet<Vec<String>> = files.iter().map(|path| module_path(&src, path)).collect();
        // the deepest known module a path names, from `base`
        let resolve = |base: &[String], parts: &[String]| -> Vec<String> {
            let mut best = base.to_vec();
            for k in 1..=parts.len() {
                let candidate = [base, &parts[..k]].concat();
                if modules.contains(&candidate) {
                    best = candidate;
                } else {
                    break;
                }
            }
            best
        };
        // parent → (child → children it references)
        let mut graphs: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
        for path in &files {
            let here = module_path(&src, path);
            let text = std::fs::read_to_string(path).unwrap();
            for line in non_test_code(&text).lines().filter(|line| !line.trim_start().starts_with("//")) {
                for (root_name, parts) in named_paths(line) {
                    let base: Vec<String> = match root_name.as_str() {
                        "crate" => Vec::new(),
                        "self" => here.clone(),
                        _ => here[..here.len().saturating_sub(1)].to_vec(),
                    };
                    let target = resolve(&base, &parts);
                    let common = here.iter().zip(&target).take_while(|(a, b)| a == b).count();
                    if common == here.len() || common == target.len() {
                        continue; // an ancestor or a descendant
                    }
                    graphs
                        .entry(here[..common].to_vec())
                        .or_default()
                        .entry(here[common].clone())
                        .or_default()
                        .insert(target[common].clone());
                }
            }
        }
        for (parent, graph) in &graphs {
            for start in graph.keys() {
                let mut stack = vec![(start.clone(), vec![start.clone()])];
                let mut seen = BTreeSet::new();
                while let Some((module, trail)) = stack.pop() {
                    for next in graph.get(&module).into_iter().flatten() {
                        if next == start {
                            let at = |name: &String| [parent.clone(), vec![name.clone()]].concat().join("::");
                            let mut members: Vec<String> = trail.iter().map(at).collect();
                            members.sort();
                            cycles.insert(format!("{krate}: {}", members.join(" ↔ ")));
                        }
                        if seen.insert(next.clone()) {
                            stack.push((next.clone(), [trail.clone(), vec![next.clone()]].concat()));
                        }
                    }
                }
            }
        }
    }
    cycles.retain(|cycle| !ALLOWED.contains(&cycle.as_str()));
    assert!(cycles.is_empty(), "module cycles (the modules of each, sorted):\n{}", Vec::from_iter(cycles).join("\n"));
}

/// No non-test Rust file is over 900 lines (an inline `mod tests` at its end not counted; the
/// WGSL beside it is not Rust). No file is exempt.
#[test]
fn no_source_file_is_over_900_lines() {
    const LIMIT: usize = 900;
    let long: Vec<String> = sources()
        .into_iter()
        .filter(|path| !test_only(path))
        .filter_map(|path| {
            let text = std::fs::read_to_string(&path).unwrap();
            let lines = non_test_code(&text).lines().count();
            let name = relative(&path);
            (lines > LIMIT).then(|| format!("{name}: {lines} lines"))
        })
        .collect();
    assert!(long.is_empty(), "files over {LIMIT} lines (split them by concept):\n{}", long.join("\n"));
}

/// Every public function has a caller outside tests: its name appears again in the non-test code
/// of some crate (an inline `mod tests` and test-only files left out) or in a template, or it is
/// listed below with the reason it stays.
#[test]
fn every_public_function_has_a_caller_outside_tests() {
    const UNCALLED: &[(&str, &str)] = &[
        ("judgment_log", "analysis/examples/active.rs prints it"),
        // issue 51: the renderer's helper decides on these GPU read-backs (tests and debugging)
        ("has_gpu_timer", "renderer: its GPU tests ask it"),
        ("read_texture_rgba32", "renderer: a debugging read-back"),
        ("read_indirect", "renderer: gpu::invariants reads the indirect buffer"),
    ];
    let mut code = String::new();
    let mut definitions = Vec::new();
    for path in sources().into_iter().filter(|path| !test_only(path)) {
        let text = std::fs::read_to_string(&path).unwrap();
        let text = non_test_code(&text);
        for line in text.lines() {
            let trimmed = line.trim_start();
            for prefix in ["pub fn ", "pub async fn ", "pub const fn "] {
                if let Some(rest) = trimmed.strip_prefix(prefix) {
                    let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
                    definitions.push((name, relative(&path)));
                }
            }
        }
        code.push_str(text);
        code.push('\n');
    }
    for entry in std::fs::read_dir(root().join("web/templates")).unwrap() {
        code.push_str(&std::fs::read_to_string(entry.unwrap().path()).unwrap_or_default());
    }
    let word = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let uncalled: Vec<String> = definitions
        .into_iter()
        .filter(|(name, _)| {
            let uses = code
                .match_indices(name.as_str())
                .filter(|(at, _)| !code[..*at].ends_with(word) && !code[at + name.len()..].starts_with(word))
                .count();
            uses < 2 && !UNCALLED.iter().any(|(listed, _)| listed == name)
        })
        .map(|(name, file)| format!("{file}: {name}"))
        .collect();
    assert!(uncalled.is_empty(), "public functions without a caller outside tests:\n{}", uncalled.join("\n"));
}
