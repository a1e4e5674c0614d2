//! End-to-end tests of `mrstudy render` and `mrstudy bench render --reference`: tiny images,
//! few samples.

use std::path::PathBuf;

use super::support::mrstudy;

fn temp_dir(name: &str) -> PathBuf {
    super::support::temp_dir("render", name)
}

/// Width and height from a PNG's IHDR chunk.
fn png_size(path: &std::path::Path) -> (u32, u32) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[1..4], b"PNG");
    (u32::from_be_bytes(b[16..20].try_into().unwrap()), u32::from_be_bytes(b[20..24].try_into().unwrap()))
}

#[test]
fn render_list_names_the_builtin_scenes() {
    let out = mrstudy().args(["render", "--list"]).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let names: Vec<&str> = text.lines().collect();
    for expected in ["survey-1", "survey-6", "dir-env-shadow", "dir-double-shadow", "lab-task"] {
        assert!(names.contains(&expected), "{expected} missing from {names:?}");
    }
}

#[test]
fn render_reference_and_photo_write_png_exr_and_buffers() {
    let dir = temp_dir("reference");
    let png = dir.join("gt.png");
    let out = mrstudy()
        .args(["render", "--scene", "lab-task", "--reference", "--spp", "2", "--size", "32x24", "--out"])
        .arg(&png)
        .arg("--buffers")
        .arg(dir.join("buffers"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(png_size(&png), (32, 24));
    for f in [
        "photo.png",
        "ground_truth.png",
        "real.exr",
        "full.exr",
        "virtual_mask.png",
        "affected_mask.png",
        "report.json",
    ] {
        assert!(dir.join("buffers").join(f).exists(), "{f} missing");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("buffers/report.json")).unwrap()).unwrap();
    assert!(report["stats"]["virtual_coverage"].as_f64().unwrap() > 0.0);

    let exr = dir.join("photo.exr");
    let out = mrstudy()
        .args(["render", "--scene", "lab-task", "--photo", "--spp", "1", "--size", "16x12", "--out"])
        .arg(&exr)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&exr).unwrap();
    assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "not an OpenEXR file");
}

#[test]
fn render_errors_are_one_sentence() {
    let out = mrstudy().args(["render", "--scene", "no-such-scene", "--reference", "--out", "x.png"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("no-such-scene") && err.trim().lines().count() == 1, "{err}");

    let dir = temp_dir("bad");
    let path = dir.join("bad.toml");
    std::fs::write(&path, "[camera]\nwidth = 8\nheight = 8\nfov_y_deg = 50.0\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[[objects]]\nshape = \"box\"\nsize = [1, 1, 1]\n").unwrap();
    let out = mrstudy().args(["render", "--reference", "--out", "x.png", "--scene"]).arg(&path).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("bad.toml") && err.contains("objects[0].role"), "{err}");
}

#[test]
fn bench_render_reference_writes_rows_and_plot() {
    let dir = temp_dir("bench");
    let json = dir.join("bench.json");
    let out = mrstudy()
        .args(["bench", "render", "--reference", "--quick", "--scene", "lab-task", "--json"])
        .arg(&json)
        .arg("--plot-dir")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = doc["rows"].as_array().unwrap();
    assert!(rows.len() >= 5);
    for row in rows {
        assert!(row["ms"].as_f64().unwrap() > 0.0 && row["rmse"].as_f64().is_some() && row["flip"].as_f64().is_some());
    }
    // error falls as samples grow
    let growing: Vec<&serde_json::Value> = rows.iter().filter(|r| r["condition"] == "reference").collect();
    let first = growing.first().unwrap()["rmse"].as_f64().unwrap();
    let last = growing.last().unwrap()["rmse"].as_f64().unwrap();
    assert!(last < first / 3.0, "{first} → {last}");
    assert!(dir.join("render_reference.svg").exists());
    // both images one world after the other, and together: the same ground truth
    let both =
        |condition: &str| rows.iter().find(|r| r["condition"] == condition).unwrap_or_else(|| panic!("{condition}"));
    let (apart, together) = (both("two passes"), both("together"));
    assert_eq!(apart["rmse"], together["rmse"]);
    assert_eq!(apart["flip"], together["flip"]);
}

#[test]
fn render_gi_method_writes_the_composite_its_buffers_and_its_errors() {
    let dir = temp_dir("gi-method");
    let png = dir.join("dit.png");
    let out = mrstudy()
        .args(["render", "--scene", "dir-lamp-box", "--gi-method", "dit", "--quality", "low"])
        .args(["--spp", "2", "--size", "40x30", "--out"])
        .arg(&png)
        .arg("--buffers")
        .arg(dir.join("buffers"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(png_size(&png), (40, 30));
    for line in ["material estimation (eq. 5)", "differential background", "against the ground truth, affected region"]
    {
        assert!(err.contains(line), "`{line}` missing from {err}");
    }
    assert!(err.contains("self-shadow tests (quality low)"), "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("buffers/report.json")).unwrap()).unwrap();
    assert_eq!(report["params"]["method"], "dit");
    assert!(report["frame"]["object_pixels"].as_u64().unwrap() > 0, "{report}");
    for f in ["composite.png", "composite.exr", "differential.exr", "albedo.png", "coverage.png", "ground_truth.png"] {
        assert!(dir.join("buffers").join(f).exists(), "{f} missing");
    }

    // an unknown method or quality: one sentence naming the choices
    let out =
        mrstudy().args(["render", "--scene", "dir-lamp-box", "--gi-method", "rt", "--out", "x.png"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("rt") && err.contains("em, dit, vct, off"), "{err}");
    let out = mrstudy()
        .args(["render", "--scene", "dir-lamp-box", "--gi-method", "em", "--quality", "ultra", "--out", "x.png"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8(out.stderr).unwrap().contains("low, med, high"));
}
