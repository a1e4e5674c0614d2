//! Axis ranges and ticks: linear axes with 1-2-5 steps, log10 axes with decade (or 1-2-5)
//! ticks, and compact tick labels.
//!
//! A range is the data range widened by [`PADDING`] of its width on each side (a single
//! value gets a range around it); ticks are the nice values inside that range.

/// Fraction of the data range added on each side of an axis.
pub(super) const PADDING: f64 = 0.05;

/// A tick label: plain text, or `mantissa×10^exponent` (drawn with a raised exponent).
#[derive(Debug, Clone, PartialEq)]
pub(super) enum TickLabel {
    Plain(String),
    Power { mantissa: Option<String>, exponent: i32 },
}

/// A data value in a tooltip (line and scatter plots): four significant digits, no trailing
/// zeros, a true minus sign.
pub(crate) fn compact(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return "0".to_owned();
    }
    let magnitude = value.abs().log10().floor();
    let text = if !(-4.0..6.0).contains(&magnitude) {
        format!("{value:.3e}")
    } else {
        let decimals = (3.0 - magnitude).max(0.0) as usize;
        let text = format!("{value:.decimals$}");
        if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.').to_owned() } else { text }
    };
    text.replace('-', "−")
}

#[cfg(test)]
impl TickLabel {
    /// The label as one line of text (for width estimates and tests): `2×10⁻⁵`.
    pub fn flat(&self) -> String {
        match self {
            TickLabel::Plain(text) => text.clone(),
            TickLabel::Power { mantissa, exponent } => {
                let mantissa = mantissa.as_ref().map(|m| format!("{m}×")).unwrap_or_default();
                format!("{mantissa}10{}", superscript(*exponent))
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(super) struct Tick {
    /// In data units.
    pub value: f64,
    pub label: TickLabel,
}

/// One axis: its range, labelled major ticks and unlabelled minor ticks.
#[derive(Debug, Clone)]
pub(super) struct Axis {
    pub log: bool,
    /// The range in axis units (log10 of the data for log axes).
    pub lo: f64,
    pub hi: f64,
    pub major: Vec<Tick>,
    /// In data units.
    pub minor: Vec<f64>,
}

impl Axis {
    /// Position of data value `value` along the axis, 0 at `lo` and 1 at `hi`.
    pub fn fraction(&self, value: f64) -> f64 {
        let axis_value = if self.log { value.log10() } else { value };
        (axis_value - self.lo) / (self.hi - self.lo)
    }

    /// A linear axis covering the finite `values`, with about `target` major ticks.
    /// Without finite values it covers [0, 1].
    pub fn linear(values: &[f64], target: usize) -> Axis {
        let (lo, hi) = finite_range(values.iter().copied()).unwrap_or((0.0, 1.0));
        let (lo, hi) = pad(widen_degenerate(lo, hi));
        let (step, values) = linear_ticks(lo, hi, target);
        let major = values
            .into_iter()
            .map(|value| Tick { value, label: TickLabel::Plain(format_linear(value, step)) })
            .collect();
        Axis { log: false, lo, hi, major, minor: Vec::new() }
    }

    /// A log10 axis covering the finite positive `values` (others are ignored), with about
    /// `target` labelled ticks: decades when the range spans three or more of them, else
    /// 1-2-5 multiples, else linear steps.
    pub fn log(values: &[f64], target: usize) -> Axis {
        let logs = values.iter().filter(|v| v.is_finite() && **v > 0.0).map(|v| v.log10());
        let (lo, hi) = finite_range(logs).unwrap_or((0.0, 1.0));
        let (lo, hi) = if hi - lo < 1e-9 { (lo - 0.5, hi + 0.5) } else { (lo, hi) };
        let (lo, hi) = pad((lo, hi));
        let (major, minor) = log_ticks(lo, hi, target);
        Axis { log: true, lo, hi, major, minor }
    }
}

fn finite_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |range, v| match range {
        None => Some((v, v)),
        Some((lo, hi)) => Some((f64::min(lo, v), f64::max(hi, v))),
    })
}

/// A range of (nearly) zero width around its value: ±10 % of the value, or ±1 around 0.
fn widen_degenerate(lo: f64, hi: f64) -> (f64, f64) {
    let magnitude = lo.abs().max(hi.abs());
    if hi - lo > 1e-9 * magnitude.max(1e-300) {
        (lo, hi)
    } else if magnitude > 1e-300 {
        (lo - 0.1 * magnitude, hi + 0.1 * magnitude)
    } else {
        (-1.0, 1.0)
    }
}

fn pad((lo, hi): (f64, f64)) -> (f64, f64) {
    let padding = PADDING * (hi - lo);
    (lo - padding, hi + padding)
}

/// The nice step (1, 2 or 5 × 10ᵏ) that puts closest to `target` ticks in `[lo, hi]`, the
/// larger step on ties, and the ticks. A range no step fits (non-finite, or empty) gets its
/// two ends as ticks.
pub(super) fn linear_ticks(lo: f64, hi: f64, target: usize) -> (f64, Vec<f64>) {
    let raw = (hi - lo) / target.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return (f64::NAN, vec![lo, hi].into_iter().filter(|v| v.is_finite()).collect());
    }
    let exponent = raw.log10().floor() as i32;
    let mut best: Option<(f64, f64)> = None;
    for candidate_exponent in exponent - 1..=exponent + 1 {
        for mantissa in [1, 2, 5] {
            let step = multiple(mantissa, candidate_exponent);
            let Some((first, last)) = tick_index_range(lo, hi, step) else {
                continue;
            };
            let count = (last - first + 1) as f64;
            let penalty = if count < 2.0 { 1e6 } else { 0.0 };
            let score = (count - target as f64).abs() + penalty;
            if best.is_none_or(|(best_score, _)| score <= best_score) {
                best = Some((score, step));
            }
        }
    }
    let Some((_, step)) = best else {
        return (f64::NAN, vec![lo, hi]);
    };
    let (first, last) = tick_index_range(lo, hi, step).unwrap_or((0, -1));
    let ticks = (first..=last).map(|index| if index == 0 { 0.0 } else { index as f64 * step }).collect();
    (step, ticks)
}

/// The integer multiples of `step` inside `[lo, hi]` (with a little tolerance), or `None`
/// for a step that does not give a sensible count.
fn tick_index_range(lo: f64, hi: f64, step: f64) -> Option<(i64, i64)> {
    if !(step.is_finite() && step > 0.0) {
        return None;
    }
    let (first, last) = ((lo / step - 1e-9).ceil(), (hi / step + 1e-9).floor());
    if !(first.is_finite() && last.is_finite()) || last - first > 1000.0 {
        return None;
    }
    Some((first as i64, last as i64))
}

/// `value` as a tick label on a linear axis with `step` between ticks: as many decimals as
/// the step needs, a minus sign (−), and scientific notation for very large or small values.
pub(super) fn format_linear(value: f64, step: f64) -> String {
    let text = if value == 0.0 && (!step.is_finite() || step < 1e-4) {
        "0".to_owned()
    } else if !step.is_finite() || value.abs() >= 1e6 || step < 1e-4 {
        let text = format!("{value:.2e}");
        match text.split_once('e') {
            Some((mantissa, exponent)) => {
                let mantissa = if mantissa.contains('.') {
                    mantissa.trim_end_matches('0').trim_end_matches('.')
                } else {
                    mantissa
                };
                format!("{mantissa}e{exponent}")
            }
            None => text,
        }
    } else {
        let decimals = (-step.log10() - 1e-9).ceil().max(0.0) as usize;
        format!("{value:.decimals$}")
    };
    // A value that rounds to zero is written without a sign.
    let text = if text.starts_with('-') && !text.chars().any(|c| ('1'..='9').contains(&c)) {
        text[1..].to_owned()
    } else {
        text
    };
    text.replace('-', "−")
}

/// Decades (or every 2nd, 5th… decade) when `[lo, hi]` (log10 units) holds three or more,
/// with unlabelled 2…9 minor ticks; else 1-2-5 multiples when three or more fit, with the
/// other multiples as minor ticks; else linear steps in data units.
fn log_ticks(lo: f64, hi: f64, target: usize) -> (Vec<Tick>, Vec<f64>) {
    let first_decade = (lo - 1e-9).ceil() as i32;
    let last_decade = (hi + 1e-9).floor() as i32;
    let n_decades = last_decade - first_decade + 1;
    let inside = |value: f64| {
        let log = value.log10();
        log >= lo - 1e-9 && log <= hi + 1e-9
    };

    if n_decades >= 3 {
        let decade_step = if n_decades as usize > target + 1 {
            let (step, _) = linear_ticks(lo, hi, target);
            if step.is_finite() { step.max(1.0).round() as i32 } else { 1 }
        } else {
            1
        };
        let labelled: Vec<i32> = (first_decade..=last_decade).filter(|k| k.rem_euclid(decade_step) == 0).collect();
        let plain = labelled.iter().all(|k| (-3..=4).contains(k));
        let major = labelled
            .iter()
            .map(|&k| Tick {
                value: pow10(k),
                label: if plain {
                    TickLabel::Plain(format_linear(pow10(k), pow10(k)))
                } else {
                    TickLabel::Power { mantissa: None, exponent: k }
                },
            })
            .collect();
        let minor = if decade_step == 1 && hi - lo <= 10.0 {
            (first_decade - 1..=last_decade)
                .flat_map(|k| (2..=9).map(move |m| multiple(m, k)))
                .filter(|v| inside(*v))
                .collect()
        } else {
            (first_decade..=last_decade).filter(|k| k.rem_euclid(decade_step) != 0).map(pow10).collect()
        };
        return (major, minor);
    }

    let multiples = |mantissas: &'static [i32]| {
        (first_decade - 1..=last_decade).flat_map(move |k| mantissas.iter().map(move |&m| (m, k, multiple(m, k))))
    };
    let one_two_five: Vec<(i32, i32, f64)> = multiples(&[1, 2, 5]).filter(|(_, _, v)| inside(*v)).collect();
    if one_two_five.len() >= 3 {
        let plain = one_two_five.iter().all(|(_, k, _)| (-3..=4).contains(k));
        let major = one_two_five
            .iter()
            .map(|&(m, k, value)| Tick {
                value,
                label: if plain {
                    TickLabel::Plain(format_linear(value, pow10(k)))
                } else if m == 1 {
                    TickLabel::Power { mantissa: None, exponent: k }
                } else {
                    TickLabel::Power { mantissa: Some(m.to_string()), exponent: k }
                },
            })
            .collect();
        let minor = multiples(&[3, 4, 6, 7, 8, 9]).map(|(_, _, v)| v).filter(|v| inside(*v)).collect();
        return (major, minor);
    }

    let (data_lo, data_hi) = (10f64.powf(lo), 10f64.powf(hi));
    let (step, values) = linear_ticks(data_lo, data_hi, target.min(5));
    let major = values
        .into_iter()
        .filter(|v| *v > 0.0)
        .map(|value| Tick { value, label: TickLabel::Plain(format_linear(value, step)) })
        .collect();
    (major, Vec::new())
}

/// 10ᵏ, correctly rounded for |k| ≤ 22 (so `pow10(-3) == 0.001`).
fn pow10(k: i32) -> f64 {
    if k >= 0 { 10f64.powi(k) } else { 1.0 / 10f64.powi(-k) }
}

/// m × 10ᵏ, correctly rounded for |k| ≤ 22 (so `multiple(5, -3) == 0.005`).
fn multiple(m: i32, k: i32) -> f64 {
    if k >= 0 { f64::from(m) * 10f64.powi(k) } else { f64::from(m) / 10f64.powi(-k) }
}

/// `exponent` in Unicode superscript digits: −3 → `⁻³`.
#[cfg(test)]
fn superscript(exponent: i32) -> String {
    exponent
        .to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOLERANCE: f64 = 1e-12;

    fn assert_close(actual: &[f64], expected: &[f64]) {
        assert_eq!(actual.len(), expected.len(), "{actual:?} vs {expected:?}");
        for (a, e) in actual.iter().zip(expected) {
            assert!((a - e).abs() <= TOLERANCE * e.abs().max(1.0), "{actual:?} vs {expected:?}");
        }
    }

    fn labels(axis: &Axis) -> Vec<String> {
        axis.major.iter().map(|tick| tick.label.flat()).collect()
    }

    #[test]
    fn linear_ticks_use_1_2_5_steps() {
        let (step, ticks) = linear_ticks(0.0, 1.0, 5);
        assert_eq!(step, 0.2);
        assert_close(&ticks, &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]);

        let (step, ticks) = linear_ticks(-0.63, 1.27, 6);
        assert_eq!(step, 0.5);
        assert_close(&ticks, &[-0.5, 0.0, 0.5, 1.0]);

        let (step, ticks) = linear_ticks(0.0, 1000.0, 5);
        assert_eq!(step, 200.0);
        assert_close(&ticks, &[0.0, 200.0, 400.0, 600.0, 800.0, 1000.0]);

        let (step, ticks) = linear_ticks(3.1, 3.4, 4);
        assert!((step - 0.1).abs() < TOLERANCE);
        assert_close(&ticks, &[3.1, 3.2, 3.3, 3.4]);
    }

    #[test]
    fn linear_ticks_survive_degenerate_ranges() {
        let (_, ticks) = linear_ticks(1.0, 1.0, 5);
        assert_eq!(ticks, vec![1.0, 1.0]);
        let (_, ticks) = linear_ticks(f64::NEG_INFINITY, 1.0, 5);
        assert_eq!(ticks, vec![1.0]);
    }

    #[test]
    fn linear_labels_are_compact() {
        assert_eq!(format_linear(0.30000000000000004, 0.1), "0.3");
        assert_eq!(format_linear(-0.5, 0.5), "−0.5");
        assert_eq!(format_linear(1.0, 0.5), "1.0");
        assert_eq!(format_linear(200.0, 100.0), "200");
        assert_eq!(format_linear(0.0, 0.2), "0.0");
        assert_eq!(format_linear(-1e-17, 0.2), "0.0");
        assert_eq!(format_linear(0.0, 1.0), "0");
        assert_eq!(format_linear(2.5e7, 5e6), "2.5e7");
        assert_eq!(format_linear(3e-5, 1e-5), "3e−5");
    }

    #[test]
    fn linear_axis_pads_and_includes_its_data() {
        let axis = Axis::linear(&[-0.6, 1.2, f64::NAN], 6);
        assert!(axis.lo < -0.6 && axis.hi > 1.2);
        assert!((axis.lo - (-0.69)).abs() < 1e-9 && (axis.hi - 1.29).abs() < 1e-9);
        assert_eq!(labels(&axis), ["−0.5", "0.0", "0.5", "1.0"]);
        assert!((axis.fraction(axis.lo)).abs() < TOLERANCE);
        assert!((axis.fraction(axis.hi) - 1.0).abs() < TOLERANCE);
    }

    #[test]
    fn linear_axis_of_one_value_or_none_is_usable() {
        let axis = Axis::linear(&[0.0], 5);
        assert!(axis.lo < 0.0 && axis.hi > 0.0);
        assert!(axis.major.len() >= 2);
        let axis = Axis::linear(&[5.0, 5.0], 5);
        assert!(axis.lo < 5.0 && axis.hi > 5.0);
        let axis = Axis::linear(&[], 5);
        assert!(axis.hi > axis.lo);
    }

    #[test]
    fn log_axis_over_many_decades_labels_decades() {
        let axis = Axis::log(&[0.001, 0.5, 200.0], 6);
        assert_eq!(labels(&axis), ["0.001", "0.01", "0.1", "1", "10", "100"]);
        assert!(axis.minor.contains(&0.002) && axis.minor.contains(&90.0));
        assert!(axis.minor.iter().all(|v| axis.fraction(*v) >= 0.0 && axis.fraction(*v) <= 1.0));
    }

    #[test]
    fn log_axis_far_from_one_uses_powers_of_ten() {
        let axis = Axis::log(&[1e-7, 1e-3], 6);
        assert_eq!(labels(&axis), ["10⁻⁷", "10⁻⁶", "10⁻⁵", "10⁻⁴", "10⁻³"]);
        assert_eq!(axis.major[0].label, TickLabel::Power { mantissa: None, exponent: -7 });
    }

    #[test]
    fn log_axis_over_very_many_decades_thins_them() {
        let axis = Axis::log(&[1e-12, 1e12], 6);
        let exponents: Vec<i32> = axis.major.iter().map(|tick| tick.value.log10().round() as i32).collect();
        assert!(exponents.len() <= 8, "{exponents:?}");
        assert!(exponents.windows(2).all(|w| w[1] - w[0] == exponents[1] - exponents[0]));
        assert!(exponents.contains(&0));
    }

    #[test]
    fn log_axis_over_one_decade_uses_1_2_5() {
        let axis = Axis::log(&[0.03, 0.9], 6);
        assert_eq!(labels(&axis), ["0.05", "0.1", "0.2", "0.5", "1"]);
        assert!(axis.minor.contains(&0.3));
    }

    #[test]
    fn log_axis_over_a_narrow_range_uses_linear_steps() {
        let axis = Axis::log(&[0.5, 0.9], 6);
        assert_eq!(labels(&axis), ["0.5", "0.6", "0.7", "0.8", "0.9"]);
    }

    #[test]
    fn log_axis_ignores_zero_negative_and_non_finite_values() {
        let axis = Axis::log(&[0.0, -3.0, f64::NAN, f64::INFINITY, 10.0, 1000.0], 6);
        assert_eq!(labels(&axis), ["10", "100", "1000"]);
        let axis = Axis::log(&[7.0], 6);
        assert!(axis.fraction(7.0) > 0.0 && axis.fraction(7.0) < 1.0);
        assert!(!axis.major.is_empty());
    }

    #[test]
    fn superscripts() {
        assert_eq!(superscript(-12), "⁻¹²");
        assert_eq!(superscript(9), "⁹");
    }

    #[test]
    fn tooltip_numbers_are_compact() {
        assert_eq!(compact(12.5), "12.5");
        assert_eq!(compact(0.0012341), "0.001234");
        assert_eq!(compact(-3.0), "−3");
        assert_eq!(compact(1.5e9), "1.500e9");
        assert_eq!(compact(f64::NAN), "0");
    }
}
