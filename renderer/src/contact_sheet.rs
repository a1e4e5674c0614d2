//! Contact sheets: a scene's ground truth, its photograph and its stimuli under several
//! conditions, rendered the way a study renders them ([`StimulusSettings`]), laid out side by
//! side in one display-encoded image, each tile labelled in a small bitmap font — to look at
//! what a scene's stimuli show against what it means to show (`mrstudy render --contact-sheet`).

use crate::error::Result;
use crate::gpu::DirRenderer;
use crate::image::Image;
use crate::scene::Scene;
use crate::stimulus::{Factors, StimulusSettings};
use glam::Vec3;

/// Tiles per row.
const COLUMNS: u32 = 5;
/// Pixels between tiles and around the sheet.
const GAP: u32 = 4;
/// The font's cells are 5×7 pixels, drawn at this scale, one pixel apart.
const FONT_SCALE: u32 = 2;
const LABEL_HEIGHT: u32 = 7 * FONT_SCALE + 6;

/// The thesis's eight rendering mode compositions, LQ … HQ: every combination of the factors
/// gi, cm and ca (the conditions the web survey compares); a contact sheet's default conditions.
pub fn rmc_conditions() -> Vec<(String, Factors)> {
    let rmcs = [("LQ", ""), ("GI", "gi"), ("CM", "cm"), ("CA", "ca"), ("GI+CM", "gi,cm")];
    let rmcs = rmcs.into_iter().chain([("GI+CA", "gi,ca"), ("CM+CA", "cm,ca"), ("HQ", "gi,cm,ca")]);
    rmcs.map(|(label, factors)| (label.to_string(), Factors::parse_list(factors).expect("a known factor list")))
        .collect()
}

/// Renders the ground truth, the photograph and `conditions` (label, factors) of `scene` (at the
/// size and samples of `settings`) and lays them out as a sheet. `progress(done, total)` counts
/// the path tracer's samples, then one step per condition.
pub fn render(
    renderer: &DirRenderer,
    scene: &Scene,
    settings: &StimulusSettings,
    conditions: &[(String, Factors)],
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<Image> {
    let scene = settings.sized(scene.clone());
    let total = 2 * settings.spp + conditions.len() as u32;
    let reference = settings.reference(&scene, &|done, _| progress(done, total))?;
    let mut tiles = vec![
        ("ground truth".to_string(), reference.ground_truth.clone()),
        ("photo".to_string(), reference.photo.clone()),
    ];
    let mut captured = None;
    for (index, (label, factors)) in conditions.iter().enumerate() {
        let frame = settings.render_stimulus(
            renderer,
            &scene,
            &reference.photo,
            &reference.hdr_real,
            factors,
            &mut captured,
        )?;
        // the condition's name, and its factors where the name does not say them
        let factors_label = factors.label();
        let tile_label = if label.eq_ignore_ascii_case(&factors_label) {
            label.clone()
        } else {
            format!("{label} ({factors_label})")
        };
        tiles.push((tile_label, frame.composite));
        progress(2 * settings.spp + index as u32 + 1, total);
    }
    Ok(layout(&tiles))
}

/// Lays display-encoded images of one size out in rows of five, each with its label above.
pub fn layout(tiles: &[(String, Image)]) -> Image {
    let (w, h) = tiles.first().map(|(_, image)| (image.width, image.height)).unwrap_or((1, 1));
    let columns = COLUMNS.min(tiles.len().max(1) as u32);
    let rows = (tiles.len() as u32).div_ceil(columns).max(1);
    let sheet_width = GAP + columns * (w + GAP);
    let sheet_height = GAP + rows * (LABEL_HEIGHT + h + GAP);
    let mut sheet = Image::filled(sheet_width, sheet_height, Vec3::splat(0.12));
    for (index, (label, image)) in tiles.iter().enumerate() {
        let (column, row) = (index as u32 % columns, index as u32 / columns);
        let x0 = GAP + column * (w + GAP);
        let y0 = GAP + row * (LABEL_HEIGHT + h + GAP);
        draw_text(&mut sheet, x0 + 1, y0 + 3, label, Vec3::splat(0.95), w);
        for y in 0..h.min(image.height) {
            for x in 0..w.min(image.width) {
                sheet.set(x0 + x, y0 + LABEL_HEIGHT + y, image.get(x, y));
            }
        }
    }
    sheet
}

/// Draws `text` (upper-cased; characters without a glyph as a box) at (x, y), clipped to
/// `max_width` pixels.
pub fn draw_text(image: &mut Image, x: u32, y: u32, text: &str, colour: Vec3, max_width: u32) {
    let advance = 6 * FONT_SCALE;
    for (index, c) in text.chars().enumerate() {
        let cx = x + index as u32 * advance;
        if cx + 5 * FONT_SCALE > x + max_width {
            break;
        }
        let rows = glyph(c.to_ascii_uppercase());
        for (row, bits) in rows.iter().enumerate() {
            for column in 0..5u32 {
                if bits >> (4 - column) & 1 == 0 {
                    continue;
                }
                for dy in 0..FONT_SCALE {
                    for dx in 0..FONT_SCALE {
                        let (px, py) = (cx + column * FONT_SCALE + dx, y + row as u32 * FONT_SCALE + dy);
                        if px < image.width && py < image.height {
                            image.set(px, py, colour);
                        }
                    }
                }
            }
        }
    }
}

/// A 5×7 glyph: seven rows, the five low bits of each (the most significant on the left).
fn glyph(c: char) -> [u8; 7] {
    match c {
        'A' => [0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11],
        'B' => [0x1e, 0x11, 0x11, 0x1e, 0x11, 0x11, 0x1e],
        'C' => [0x0e, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0e],
        'D' => [0x1e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1e],
        'E' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f],
        'F' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x10],
        'G' => [0x0e, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0f],
        'H' => [0x11, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11],
        'I' => [0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0c],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1f],
        'M' => [0x11, 0x1b, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'P' => [0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10],
        'Q' => [0x0e, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0d],
        'R' => [0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11],
        'S' => [0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e],
        'T' => [0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0a, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0a],
        'X' => [0x11, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x0a, 0x04, 0x04, 0x04, 0x04],
        'Z' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1f],
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        ' ' => [0; 7],
        '+' => [0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00],
        '-' => [0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c],
        ',' => [0x00, 0x00, 0x00, 0x00, 0x0c, 0x04, 0x08],
        ':' => [0x00, 0x0c, 0x0c, 0x00, 0x0c, 0x0c, 0x00],
        '/' => [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '=' => [0x00, 0x00, 0x1f, 0x00, 0x1f, 0x00, 0x00],
        '_' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1f],
        _ => [0x1f, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1f],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layout_places_each_tile_below_its_label_in_rows_of_five() {
        let tiles: Vec<(String, Image)> =
            (0..7).map(|i| (format!("T{i}"), Image::filled(10, 8, Vec3::splat(i as f32 / 10.0)))).collect();
        let sheet = layout(&tiles);
        assert_eq!(sheet.width, GAP + 5 * (10 + GAP));
        assert_eq!(sheet.height, GAP + 2 * (LABEL_HEIGHT + 8 + GAP));
        // tile 6 is the second of the second row
        let (x0, y0) = (GAP + (10 + GAP), GAP + (LABEL_HEIGHT + 8 + GAP) + LABEL_HEIGHT);
        assert_eq!(sheet.get(x0, y0), Vec3::splat(0.6));
        assert_eq!(sheet.get(x0 + 9, y0 + 7), Vec3::splat(0.6));
        // its label is drawn: some light pixels in the band above it
        let label_lit = (y0 - LABEL_HEIGHT..y0).any(|y| (x0..x0 + 10).any(|x| sheet.get(x, y).x > 0.9));
        assert!(label_lit);
    }

    #[test]
    fn every_label_character_has_its_own_glyph() {
        let unknown = glyph('\u{1}');
        for c in "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789+-.,:/()=_".chars() {
            assert_ne!(glyph(c), unknown, "{c}");
        }
        assert_eq!(glyph('a'.to_ascii_uppercase()), glyph('A'));
    }
}
