//! Smaller defects of the participant pages (issue 45, item 5) in headless Chromium against a
//! real `mrstudy serve`: a phone is told to tap (not to click or press arrow keys), every page
//! has a favicon (no 404), the keyboard focus ring has at least 3:1 contrast against the panel
//! and the page, and the consent checkbox is at least 20 px.

use serde_json::{Value, json};

use super::browser::{Driver, browser_available, screenshot_path};
use super::support::{Server, client};
use super::survey_input::{enter, phone};

#[test]
fn a_phone_is_told_to_tap_and_a_desktop_to_click_or_press_a_key() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    for (driver, device, expected) in
        [(phone(), "phone", "Tap an image."), (Driver::start(1280, 800), "desktop", "Click an image, or press ← or →.")]
    {
        enter(&driver, &server.base, "");
        driver.click("#start");
        driver.wait_trial("1");
        driver.screenshot(&screenshot_path(&format!("polish-trial-{device}.png")));
        assert_eq!(driver.text("#stage-trial .hint"), expected, "{device}");
    }
}

/// Fetches `url` from the page (same origin) and returns [status, content type].
fn fetch_from_page(driver: &Driver, url: &str) -> Value {
    driver.script(&format!(
        "const x = new XMLHttpRequest(); x.open('GET', {url:?}, false); x.send();
         return [x.status, x.getResponseHeader('Content-Type') || ''];"
    ))
}

#[test]
fn every_page_names_a_favicon_that_is_served_and_favicon_ico_is_no_404() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 800);
    for path in ["/", "/studies/shadows-demo", "/studies/no-such-study", "/admin"] {
        driver.go(&format!("{}{path}", server.base));
        let icon = driver.script("const l = document.querySelector(\"link[rel~='icon']\"); return l ? l.href : null;");
        let icon = icon.as_str().unwrap_or_else(|| panic!("{path}: no <link rel=icon>")).to_string();
        let answer = fetch_from_page(&driver, &icon);
        assert_eq!(answer[0], json!(200), "{path}: {icon} {answer}");
        assert!(answer[1].as_str().unwrap().starts_with("image/"), "{path}: {icon} {answer}");
    }
    let answer = client().get(format!("{}/favicon.ico", server.base)).send().unwrap();
    assert_eq!(answer.status(), 200);
    let kind = answer.headers()["content-type"].to_str().unwrap().to_string();
    assert!(kind.starts_with("image/"), "{kind}");
}

/// sRGB relative luminance of "rgb(r, g, b)" / "rgba(r, g, b, a)".
fn luminance(css: &str) -> f64 {
    let inner = css.split('(').nth(1).unwrap().trim_end_matches(')');
    let channels: Vec<f64> = inner.split(',').take(3).map(|c| c.trim().parse::<f64>().unwrap() / 255.0).collect();
    let linear = |c: f64| if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) };
    0.2126 * linear(channels[0]) + 0.7152 * linear(channels[1]) + 0.0722 * linear(channels[2])
}

fn contrast(a: &str, b: &str) -> f64 {
    let (la, lb) = (luminance(a), luminance(b));
    (la.max(lb) + 0.05) / (la.min(lb) + 0.05)
}

#[test]
fn the_focus_ring_has_3_to_1_contrast_and_the_consent_checkbox_is_at_least_20_px() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    for (driver, device) in [(Driver::start(1280, 800), "desktop"), (phone(), "phone")] {
        driver.go(&format!("{}/studies/shadows-demo", server.base));
        driver.wait_visible("stage-welcome");
        let size = driver.script(
            "const r = document.getElementById('consent').getBoundingClientRect(); return [r.width, r.height];",
        );
        let (width, height) = (size[0].as_f64().unwrap(), size[1].as_f64().unwrap());
        // Tab to the checkbox and on to the button: each shows a ring the keyboard user can see.
        let backgrounds = driver.script(
            "return [getComputedStyle(document.querySelector('#stage-welcome')).backgroundColor,
                     getComputedStyle(document.body).backgroundColor];",
        );
        let mut seen = Vec::new();
        for _ in 0..6 {
            driver.type_into("body", "\u{E004}"); // Tab
            let focused = driver.script(
                "const e = document.activeElement, s = getComputedStyle(e);
                 return [e.id, e.matches(':focus-visible'), s.outlineStyle, parseFloat(s.outlineWidth), s.outlineColor];",
            );
            let id = focused[0].as_str().unwrap().to_string();
            if id != "consent" && id != "consent-continue" {
                continue;
            }
            if id == "consent" {
                driver.screenshot(&screenshot_path(&format!("polish-focus-{device}.png")));
            }
            assert_eq!(focused[1], json!(true), "{device}: {focused}");
            assert_ne!(focused[2], json!("none"), "{device}: no ring on #{id}: {focused}");
            assert!(focused[3].as_f64().unwrap() >= 2.0, "{device}: a thin ring on #{id}: {focused}");
            for background in backgrounds.as_array().unwrap() {
                let ratio = contrast(focused[4].as_str().unwrap(), background.as_str().unwrap());
                assert!(ratio >= 3.0, "{device}: the ring of #{id} has {ratio:.2}:1 against {background}: {focused}");
            }
            seen.push(id);
            if seen.len() == 2 {
                break;
            }
        }
        assert_eq!(seen, ["consent", "consent-continue"], "{device}: Tab did not reach the consent form");
        assert!(width >= 20.0 && height >= 20.0, "{device}: the consent checkbox is {width}×{height} px");
    }
}
