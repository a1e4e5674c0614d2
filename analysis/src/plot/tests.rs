//! Tests of the SVG plots: structure, labels and numbers of the worth and factor-effect plots.

use super::*;

const CONDITIONS: [&str; 8] = ["LQ", "GI", "CM", "CA", "GI+CM", "GI+CA", "CM+CA", "HQ"];

fn conditions() -> Vec<String> {
    CONDITIONS.iter().map(|c| (*c).to_owned()).collect()
}

fn point(condition: &str, log_worth: f64, half_width: Option<f64>) -> WorthPoint {
    WorthPoint {
        condition: condition.to_owned(),
        log_worth,
        low: half_width.map(|h| log_worth - h),
        high: half_width.map(|h| log_worth + h),
    }
}

/// Made-up log-worths shaped like the thesis' web survey: LQ is the reference (0, no
/// interval), the others between −0.6 and 1.2 with intervals of ±0.1…0.2.
fn thesis_like_worths() -> Vec<WorthSeries> {
    let groups: [(&str, [f64; 8]); 3] = [
        ("all", [0.0, 0.55, 0.31, -0.42, 0.93, 0.21, -0.08, 1.12]),
        ("female", [0.0, 0.47, 0.40, -0.56, 0.88, 0.10, 0.02, 1.05]),
        ("male", [0.0, 0.63, 0.22, -0.30, 1.01, 0.30, -0.17, 1.19]),
    ];
    groups
        .iter()
        .enumerate()
        .map(|(group_idx, (name, log_worths))| WorthSeries {
            name: (*name).to_owned(),
            points: CONDITIONS
                .iter()
                .zip(log_worths)
                .enumerate()
                .map(|(idx, (condition, &lw))| {
                    let half = 0.1 + 0.1 * ((idx + group_idx) % 5) as f64 / 4.0;
                    point(condition, lw, (idx > 0).then_some(half + 0.03 * group_idx as f64))
                })
                .collect(),
        })
        .collect()
}

fn thesis_like_effects() -> (Vec<String>, Vec<EffectSeries>) {
    let factors = ["gi", "cm", "ca", "gi:cm", "gi:ca", "cm:ca"];
    let groups: [(&str, [f64; 6]); 3] = [
        ("all", [0.54, 0.31, -0.42, 0.08, 0.12, -0.05]),
        ("female", [0.47, 0.40, -0.56, 0.01, 0.19, 0.04]),
        ("male", [0.62, 0.22, -0.30, 0.15, 0.05, -0.13]),
    ];
    let series = groups
        .iter()
        .enumerate()
        .map(|(group_idx, (name, estimates))| EffectSeries {
            name: (*name).to_owned(),
            points: factors
                .iter()
                .zip(estimates)
                .map(|(factor, &estimate)| {
                    let half = 0.11 + 0.04 * group_idx as f64;
                    EffectPoint {
                        factor: (*factor).to_owned(),
                        estimate,
                        low: Some(estimate - half),
                        high: Some(estimate + half),
                    }
                })
                .collect(),
        })
        .collect();
    (factors.iter().map(|f| (*f).to_owned()).collect(), series)
}

fn benchmark() -> LinePlot {
    let cpu = [(1.0, 0.21), (4.0, 0.11), (16.0, 0.052), (64.0, 0.027), (256.0, 0.013), (1024.0, 0.0066)];
    let gpu = [(16.0, 0.081), (64.0, 0.052), (256.0, 0.038), (1024.0, 0.033)];
    LinePlot {
        title: "Render time against error".to_owned(),
        x_label: "time per frame (ms)".to_owned(),
        y_label: "RMSE against the reference".to_owned(),
        x_log: true,
        y_log: true,
        series: vec![
            LineSeries {
                name: "CPU path tracer (spp)".to_owned(),
                points: cpu.iter().map(|&(spp, e)| (18.0 * spp, e)).collect(),
            },
            LineSeries {
                name: "GPU DIR (VPLs)".to_owned(),
                points: gpu.iter().map(|&(vpls, e)| (1.2 + 0.05 * vpls, e)).collect(),
            },
            LineSeries {
                name: "GPU DIR + colour mapping".to_owned(),
                points: gpu.iter().map(|&(vpls, e)| (1.9 + 0.05 * vpls, e * 0.8)).chain([(60.0, 0.0)]).collect(),
            },
        ],
    }
}

/// Parses `svg` as XML, checks the basics every figure must meet, and returns the text
/// of its `<text>` elements (tooltips excluded).
fn check(svg: &str) -> Vec<String> {
    for forbidden in ["NaN", "inf", "Inf"] {
        assert!(!svg.contains(forbidden), "SVG contains {forbidden}:\n{svg}");
    }
    let document = roxmltree::Document::parse(svg).unwrap_or_else(|e| panic!("not XML: {e}\n{svg}"));
    let root = document.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert_eq!(root.tag_name().namespace(), Some("http://www.w3.org/2000/svg"));
    for attribute in ["width", "height"] {
        let value: f64 = root.attribute(attribute).unwrap().parse().unwrap();
        assert!(value > 0.0 && value < 10_000.0, "{attribute} = {value}");
    }
    root.descendants()
        .filter(|node| node.has_tag_name("text"))
        .map(|node| {
            node.children()
                .filter(|child| !child.has_tag_name("title"))
                .map(|child| child.text().unwrap_or(""))
                .collect()
        })
        .collect()
}

fn tooltips(svg: &str) -> Vec<String> {
    let document = roxmltree::Document::parse(svg).unwrap();
    document
        .descendants()
        .filter(|node| node.has_tag_name("title") && node.parent().is_some_and(|p| !p.has_tag_name("svg")))
        .map(|node| node.text().unwrap_or("").to_owned())
        .collect()
}

/// Every bold (title) line of `svg`, with its estimated left and right edges and the
/// figure's view-box width.
fn title_extents(svg: &str) -> (f64, Vec<(String, f64, f64)>) {
    let document = roxmltree::Document::parse(svg).unwrap();
    let root = document.root_element();
    let view_box: Vec<f64> = root.attribute("viewBox").unwrap().split(' ').map(|v| v.parse().unwrap()).collect();
    let lines = root
        .descendants()
        .filter(|node| node.has_tag_name("text") && node.attribute("font-weight") == Some("bold"))
        .map(|node| {
            let text = node.text().unwrap_or("").to_owned();
            let x: f64 = node.attribute("x").unwrap().parse().unwrap();
            let size: f64 = node.attribute("font-size").unwrap().parse().unwrap();
            let width = svg::text_width(&text, size) * svg::BOLD_WIDTH;
            let (left, right) = match node.attribute("text-anchor") {
                Some("middle") => (x - width / 2.0, x + width / 2.0),
                Some("end") => (x - width, x),
                _ => (x, x + width),
            };
            (text, left, right)
        })
        .collect();
    (view_box[2], lines)
}

#[test]
fn long_titles_fit_inside_the_view_box() {
    let long = "Preference for rendering modes in the web survey of 2026, all participants \
                who completed it on a phone or a tablet, 95\u{a0}% intervals";
    let worths = thesis_like_worths();
    let (factors, effects) = thesis_like_effects();
    // The analysis' own title with the longest condition name of the thesis' design.
    let worth_title = "Worth of each condition (log scale, reference GI+CM+CA), 95\u{a0}% intervals";
    let figures = [
        (long, worth_plot(long, &conditions(), &worths)),
        (worth_title, worth_plot(worth_title, &conditions(), &worths[..1])),
        (long, effect_plot(long, &factors, &effects)),
        (long, line_plot(&LinePlot { title: long.to_owned(), ..benchmark() })),
        (long, worth_plot(long, &[], &[])),
    ];
    for (title, svg) in &figures {
        check(svg);
        let (width, lines) = title_extents(svg);
        for (text, left, right) in &lines {
            assert!(
                *left >= 0.0 && *right <= width,
                "title line `{text}` spans {left:.1}..{right:.1}, view box 0..{width}"
            );
        }
        // Wrapped, not widened without bound, and no word lost.
        assert!(width < 800.0, "width {width}");
        let joined: Vec<&str> = lines.iter().map(|(text, ..)| text.as_str()).collect();
        assert_eq!(joined.join(" "), *title);
    }
    // The no-break space holds "95 %" together.
    let (_, lines) = title_extents(&figures[0].1);
    assert!(lines.iter().any(|(text, ..)| text.ends_with("95\u{a0}% intervals")));
}

#[test]
fn worth_plot_is_svg_with_every_condition_and_group() {
    let svg = worth_plot("Web survey: all scenes", &conditions(), &thesis_like_worths());
    let texts = check(&svg);
    for label in CONDITIONS.iter().chain(&["all", "female", "male", "Web survey: all scenes"]) {
        assert!(texts.iter().any(|t| t == label), "missing {label}: {texts:?}");
    }
    assert!(texts.iter().any(|t| t.starts_with("log-worth λ")));
    assert_eq!(tooltips(&svg).len(), 3 * CONDITIONS.len());
}

#[test]
fn worth_plot_keeps_the_given_condition_order() {
    let svg = worth_plot("", &conditions(), &thesis_like_worths());
    let texts = check(&svg);
    let positions: Vec<usize> = CONDITIONS.iter().map(|c| texts.iter().position(|t| t == c).unwrap()).collect();
    assert!(positions.windows(2).all(|w| w[0] < w[1]), "{positions:?}");
}

#[test]
fn worth_plot_escapes_markup_in_names() {
    let names = vec!["<b>GI & CM</b>".to_owned(), "LQ".to_owned()];
    let series = vec![WorthSeries {
        name: "\"men\" & <women>".to_owned(),
        points: vec![point("<b>GI & CM</b>", 0.4, Some(0.1)), point("LQ", 0.0, None)],
    }];
    let svg = worth_plot("a < b & c > d", &names, &series);
    assert!(!svg.contains("<b>") && !svg.contains("& "));
    let texts = check(&svg);
    for label in ["<b>GI & CM</b>", "\"men\" & <women>", "a < b & c > d"] {
        assert!(texts.iter().any(|t| t == label), "missing {label}: {texts:?}");
    }
}

#[test]
fn worth_plot_draws_no_bar_without_an_interval() {
    let bar = r#"stroke-width="1.6""#;
    let names = vec!["LQ".to_owned()];
    let series = |low, high| {
        vec![WorthSeries {
            name: "all".to_owned(),
            points: vec![WorthPoint { condition: "LQ".to_owned(), log_worth: 0.3, low, high }],
        }]
    };
    assert_eq!(worth_plot("", &names, &series(None, None)).matches(bar).count(), 0);
    assert_eq!(worth_plot("", &names, &series(Some(0.1), Some(0.5))).matches(bar).count(), 3);
    assert_eq!(worth_plot("", &names, &series(None, Some(0.5))).matches(bar).count(), 2);
    assert_eq!(worth_plot("", &names, &series(Some(f64::NAN), Some(f64::INFINITY))).matches(bar).count(), 0);
    check(&worth_plot("", &names, &series(Some(f64::NAN), Some(0.5))));
}

#[test]
fn worth_plot_leaves_out_missing_points_but_keeps_their_rows() {
    let mut series = thesis_like_worths();
    series[2].points.retain(|p| p.condition != "CM+CA");
    series[1].points[3].log_worth = f64::NAN;
    let svg = worth_plot("missing", &conditions(), &series);
    let texts = check(&svg);
    assert!(texts.iter().any(|t| t == "CM+CA"));
    let tooltips = tooltips(&svg);
    assert_eq!(tooltips.len(), 3 * CONDITIONS.len() - 2);
    assert!(!tooltips.iter().any(|t| t.starts_with("CM+CA (male)")));
}

#[test]
fn worth_plot_appends_conditions_not_in_the_list() {
    let svg = worth_plot("", &["LQ".to_owned()], &thesis_like_worths());
    let texts = check(&svg);
    for label in CONDITIONS {
        assert!(texts.iter().any(|t| t == label), "missing {label}");
    }
}

#[test]
fn worth_column_shows_normalised_worths() {
    let names = vec!["LQ".to_owned(), "HQ".to_owned(), "GI".to_owned()];
    let series = vec![
        WorthSeries { name: "all".to_owned(), points: vec![point("LQ", 0.0, None), point("HQ", 3f64.ln(), Some(0.2))] },
        WorthSeries { name: "male".to_owned(), points: vec![point("LQ", 0.0, None), point("GI", -20.0, None)] },
    ];
    let options = WorthPlotOptions { show_worth: true, reference: Some("LQ".to_owned()) };
    let svg = worth_plot_with("", &names, &series, &options);
    let texts = check(&svg);
    for cell in ["worth π", "0.250", "0.750", "1.000", "<0.001", "–", "log-worth λ (logit scale, LQ = 0)"] {
        assert!(texts.iter().any(|t| t == cell), "missing {cell}: {texts:?}");
    }
}

#[test]
fn worth_plot_handles_many_long_conditions() {
    let names: Vec<String> = (0..50).map(|i| format!("condition number {i} with a long name, really long")).collect();
    let series: Vec<WorthSeries> = ["all", "female", "male"]
        .iter()
        .map(|group| WorthSeries {
            name: (*group).to_owned(),
            points: names.iter().enumerate().map(|(i, n)| point(n, (i as f64 * 0.37).sin(), Some(0.15))).collect(),
        })
        .collect();
    let svg = worth_plot_with("fifty", &names, &series, &WorthPlotOptions { show_worth: true, reference: None });
    let texts = check(&svg);
    assert!(texts.iter().filter(|t| t.starts_with("condition number") && t.ends_with('…')).count() == 50);
    let tooltips = tooltips(&svg);
    assert!(tooltips.iter().any(|t| t == &names[49]));
    assert_eq!(tooltips.len(), 50 + 150);
}

#[test]
fn empty_inputs_give_a_no_data_figure() {
    let no_points = vec![WorthSeries { name: "all".to_owned(), points: vec![point("LQ", f64::NAN, Some(1.0))] }];
    let figures = [
        worth_plot("nothing", &[], &[]),
        worth_plot("nothing", &conditions(), &[]),
        worth_plot("nothing", &conditions(), &no_points),
        effect_plot("nothing", &[], &[]),
        line_plot(&LinePlot::default()),
        line_plot(&LinePlot {
            x_log: true,
            series: vec![LineSeries { name: "s".to_owned(), points: vec![(0.0, 1.0), (f64::NAN, 2.0)] }],
            ..LinePlot::default()
        }),
    ];
    for svg in figures {
        let texts = check(&svg);
        assert!(texts.iter().any(|t| t == "no data"), "{svg}");
    }
}

#[test]
fn effect_plot_shows_every_factor_and_group() {
    let (factors, series) = thesis_like_effects();
    let svg = effect_plot("Factor effects", &factors, &series);
    let texts = check(&svg);
    for label in
        factors.iter().map(String::as_str).chain(["all", "female", "male", "effect on log-worth (logit scale)"])
    {
        assert!(texts.iter().any(|t| t == label), "missing {label}");
    }
    assert!(tooltips(&svg).iter().any(|t| t == "gi (all): β = 0.54, 95 % CI [0.43, 0.65]"));
}

#[test]
fn line_plot_has_series_labels_and_decade_ticks() {
    let svg = line_plot(&benchmark());
    let texts = check(&svg);
    for label in [
        "CPU path tracer (spp)",
        "GPU DIR (VPLs)",
        "GPU DIR + colour mapping",
        "time per frame (ms)",
        "RMSE against the reference",
        "10",
        "100",
        "1000",
        "0.01",
        "0.1",
    ] {
        assert!(texts.iter().any(|t| t == label), "missing {label}: {texts:?}");
    }
    assert!(texts.iter().any(|t| t == "1 point not shown (not finite, or not positive on a log axis)."));
    assert_eq!(svg.matches("<polyline").count(), 3);
}

#[test]
fn line_plot_skips_points_a_log_axis_cannot_show() {
    let spec = LinePlot {
        title: "log".to_owned(),
        x_label: "x".to_owned(),
        y_label: "y".to_owned(),
        x_log: true,
        y_log: true,
        series: vec![LineSeries {
            name: "s".to_owned(),
            points: vec![
                (0.0, 1.0),
                (-1.0, 1.0),
                (1.0, 0.0),
                (1.0, -2.0),
                (f64::INFINITY, 1.0),
                (1.0, 2.0),
                (10.0, 20.0),
                (100.0, 30.0),
            ],
        }],
    };
    let svg = line_plot(&spec);
    let texts = check(&svg);
    assert!(texts.iter().any(|t| t == "5 points not shown (not finite, or not positive on a log axis)."));
    assert_eq!(tooltips(&svg).len(), 3);
}

#[test]
fn line_plot_on_linear_axes_keeps_negative_values() {
    let spec = LinePlot {
        series: vec![LineSeries { name: "s".to_owned(), points: vec![(-1.0, -5.0), (0.0, 0.0), (2.0, 1e-3)] }],
        ..LinePlot::default()
    };
    let svg = line_plot(&spec);
    check(&svg);
    assert_eq!(tooltips(&svg).len(), 3);
    assert!(!svg.contains("not shown"));
}

#[test]
fn line_plot_with_power_of_ten_ticks_is_well_formed() {
    let spec = LinePlot {
        y_log: true,
        series: vec![LineSeries { name: "s".to_owned(), points: vec![(1.0, 1e-9), (2.0, 1e-6), (3.0, 1e-4)] }],
        ..LinePlot::default()
    };
    let svg = line_plot(&spec);
    let texts = check(&svg);
    assert!(texts.iter().any(|t| t == "10−9"), "{texts:?}");
}

/// Writes the example figures to `$MRSTUDY_PLOT_DIR` for looking at them
/// (`MRSTUDY_PLOT_DIR=/tmp cargo test -p mrstudy-analysis plot::tests::write -- --ignored`).
#[test]
#[ignore = "writes example figures to $MRSTUDY_PLOT_DIR"]
fn write_example_figures() {
    let Some(dir) = std::env::var_os("MRSTUDY_PLOT_DIR") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    let options = WorthPlotOptions { show_worth: true, reference: Some("LQ".to_owned()) };
    let (factors, effects) = thesis_like_effects();
    let mut missing = thesis_like_worths();
    missing[2].points.retain(|p| p.condition != "CM+CA");
    missing[1].points[2].low = None;
    missing[1].points[2].high = None;
    let long: Vec<String> = (0..30)
        .map(|i| {
            format!("scene {} · {}", i / 8, ["LQ", "GI", "CM", "CA", "GI+CM+CA with adaptive colour mapping"][i % 5])
        })
        .collect();
    let long_series: Vec<WorthSeries> = ["all", "female", "male"]
        .iter()
        .enumerate()
        .map(|(g, name)| WorthSeries {
            name: (*name).to_owned(),
            points: long
                .iter()
                .enumerate()
                .map(|(i, c)| point(c, (i as f64 * 0.37 + g as f64 * 0.2).sin(), Some(0.12 + 0.02 * g as f64)))
                .collect(),
        })
        .collect();
    let figures = [
        ("worth.svg", worth_plot("Preference for rendering modes (web survey)", &conditions(), &thesis_like_worths())),
        (
            "worth-pi.svg",
            worth_plot_with("Preference for rendering modes (web survey)", &conditions(), &missing, &options),
        ),
        ("worth-long.svg", worth_plot_with("Thirty long conditions", &long, &long_series, &options)),
        ("effect.svg", effect_plot("Effects of the rendering factors", &factors, &effects)),
        ("line.svg", line_plot(&benchmark())),
        ("empty.svg", worth_plot("Nothing yet", &[], &[])),
        (
            "worth-one.svg",
            worth_plot_with(
                "One group",
                &conditions(),
                &thesis_like_worths()[..1],
                &WorthPlotOptions { show_worth: true, reference: None },
            ),
        ),
        (
            "line-linear.svg",
            line_plot(&LinePlot {
                title: "Frame time against virtual point lights".to_owned(),
                x_label: "virtual point lights".to_owned(),
                y_label: "time per frame (ms)".to_owned(),
                series: vec![
                    LineSeries {
                        name: "1280×720".to_owned(),
                        points: (1..=8).map(|i| (128.0 * f64::from(i), 2.0 + 1.7 * f64::from(i))).collect(),
                    },
                    LineSeries {
                        name: "1920×1080".to_owned(),
                        points: (1..=8).map(|i| (128.0 * f64::from(i), 3.1 + 3.9 * f64::from(i))).collect(),
                    },
                ],
                ..LinePlot::default()
            }),
        ),
    ];
    for (name, svg) in figures {
        std::fs::write(dir.join(name), svg).unwrap();
    }
}
