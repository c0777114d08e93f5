//! Raw sensor frames of the array (Note S3): every sensor pixel looks through the lens whose
//! sub-image holds it, back along the lens mapping to a direction, and from there into the
//! ideal 135° scene (one equiangular 45°×45° tile per lens); and the dot-grid target.

use rayon::prelude::*;

use super::layout::ArrayLayout;
use super::projection::{angles, direction, project, unproject};
use crate::error::{Error, Result};
use crate::scene::texture::sample_bilinear;
use crate::types::Image;

/// Stitched-image position `(x, y)` (pixels, centres at integers) of scene angles `(h, v)` in
/// lens `i`'s tile, or `None` outside the tile.
pub fn tile_position(layout: &ArrayLayout, i: usize, h: f64, v: f64) -> Option<(f64, f64)> {
    let fov = layout.tile_fov_deg.to_radians();
    let t = layout.lenses[i].tilt_deg.to_radians();
    let (u, w) = ((h - t) / fov + 0.5, v / fov + 0.5);
    if !(0.0..=1.0).contains(&u) || !(0.0..=1.0).contains(&w) {
        return None;
    }
    let n = layout.tile_px as f64;
    Some((i as f64 * n + u * n - 0.5, w * n - 0.5))
}

/// Scene angles `(h, v)` of stitched-image pixel `(x, y)`.
pub fn tile_angles(layout: &ArrayLayout, x: f64, y: f64) -> (usize, f64, f64) {
    let n = layout.tile_px as f64;
    let i = ((x / n).floor().max(0.0) as usize).min(layout.lenses.len() - 1);
    let fov = layout.tile_fov_deg.to_radians();
    let t = layout.lenses[i].tilt_deg.to_radians();
    (
        (i),
        t + ((x + 0.5 - i as f64 * n) / n - 0.5) * fov,
        ((y + 0.5) / n - 0.5) * fov,
    )
}

/// Sensor position (pixels) of stitched pixel `(x, y)` through the nominal lens model.
pub fn nominal_sensor_position(layout: &ArrayLayout, x: f64, y: f64) -> Option<(usize, f64, f64)> {
    let (i, h, v) = tile_angles(layout, x, y);
    let (ax, ay) = direction(h, v);
    let l = &layout.lenses[i];
    let (dx, dy) = project(
        layout.profile,
        layout.focal_px(),
        l.tilt_deg.to_radians(),
        ax,
        ay,
    )?;
    Some((i, l.axis_px[0] + dx, l.axis_px[1] + dy))
}

/// Which lens images sensor pixel `(x, y)`, and where in the stitched image that point is.
pub fn sensor_to_tile(layout: &ArrayLayout, x: f64, y: f64) -> Option<(usize, f64, f64)> {
    let f = layout.focal_px();
    let mut found = None;
    for (i, l) in layout.lenses.iter().enumerate() {
        let Some((ax, ay)) = unproject(
            layout.profile,
            f,
            l.tilt_deg.to_radians(),
            x - l.axis_px[0],
            y - l.axis_px[1],
        ) else {
            continue;
        };
        let Some((h, v)) = angles(ax, ay) else {
            continue;
        };
        if let Some((tx, ty)) = tile_position(layout, i, h, v) {
            found = Some((i, tx, ty));
            break;
        }
    }
    found
}

/// Fails when two lenses would image onto one sensor pixel or a sub-image leaves the sensor.
pub fn check_layout(layout: &ArrayLayout) -> Result<()> {
    layout.validate()?;
    let f = layout.focal_px();
    let [h, w] = layout.sensor;
    // Sample each tile's border: it must land on the sensor.
    let n = layout.tile_px as f64;
    for i in 0..layout.lenses.len() {
        for k in 0..=64 {
            let s = k as f64 / 64.0 * (n - 1.0);
            for (x, y) in [(s, 0.0), (s, n - 1.0), (0.0, s), (n - 1.0, s)] {
                let Some((_, sx, sy)) = nominal_sensor_position(layout, i as f64 * n + x, y) else {
                    return Err(Error::invalid(
                        "array layout",
                        format!("lens {} cannot image its whole tile", i + 1),
                    ));
                };
                if sx < 0.0 || sy < 0.0 || sx > w as f64 - 1.0 || sy > h as f64 - 1.0 {
                    return Err(Error::invalid(
                        "array layout",
                        format!(
                            "lens {}'s sub-image leaves the {w}x{h} sensor near ({sx:.0}, {sy:.0})",
                            i + 1
                        ),
                    ));
                }
            }
        }
    }
    // No pixel may be claimed twice.
    let clash = (0..h).into_par_iter().find_map_any(|y| {
        (0..w).find_map(|x| {
            let claims = layout
                .lenses
                .iter()
                .enumerate()
                .filter(|(i, l)| {
                    unproject(
                        layout.profile,
                        f,
                        l.tilt_deg.to_radians(),
                        x as f64 - l.axis_px[0],
                        y as f64 - l.axis_px[1],
                    )
                    .and_then(|(ax, ay)| angles(ax, ay))
                    .and_then(|(hh, vv)| tile_position(layout, *i, hh, vv))
                    .is_some()
                })
                .count();
            (claims > 1).then_some((x, y))
        })
    });
    if let Some((x, y)) = clash {
        return Err(Error::invalid(
            "array layout",
            format!("two sub-images overlap at sensor pixel ({x}, {y})"),
        ));
    }
    Ok(())
}

/// The raw frame `[C, H_sensor, W_sensor]` of an ideal stitched-geometry scene `wide`
/// (`[C, tile, tile·lenses]`), without the camera model. Pixels no lens images are black.
pub fn render_raw(layout: &ArrayLayout, wide: &Image) -> Result<Image> {
    let [th, tw] = layout.wide_size();
    if (wide.height(), wide.width()) != (th, tw) {
        return Err(Error::shape(
            "wide scene",
            format!("{tw}x{th}"),
            format!("{}x{}", wide.width(), wide.height()),
        ));
    }
    let [h, w] = layout.sensor;
    let c = wide.channels();
    let rows: Vec<Vec<f32>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut row = vec![0.0f32; c * w];
            for x in 0..w {
                if let Some((i, tx, ty)) = sensor_to_tile(layout, x as f64, y as f64) {
                    // Clamp inside the lens's own tile so that no neighbour tile bleeds in.
                    let n = layout.tile_px as f64;
                    let tx = tx.clamp(i as f64 * n, (i + 1) as f64 * n - 1.0);
                    let ty = ty.clamp(0.0, n - 1.0);
                    for ch in 0..c {
                        row[ch * w + x] = sample_bilinear(wide, ch, tx as f32, ty as f32);
                    }
                }
            }
            row
        })
        .collect();
    let mut data = vec![0.0f32; c * h * w];
    for (y, row) in rows.iter().enumerate() {
        for ch in 0..c {
            data[ch * h * w + y * w..ch * h * w + (y + 1) * w]
                .copy_from_slice(&row[ch * w..(ch + 1) * w]);
        }
    }
    Image::from_vec(c, h, w, data)
}

/// Dot centres `(x, y)` in stitched pixels, one list per tile.
pub type DotCentres = Vec<Vec<(f64, f64)>>;

/// The calibration target in stitched geometry: `per_side × per_side` dark dots per tile on
/// white, at the centres of a regular lattice, anti-aliased; returns the image and the dot
/// centres `(x, y)` (stitched pixels), tile by tile.
pub fn dot_grid_target(layout: &ArrayLayout, per_side: usize) -> Result<(Image, DotCentres)> {
    if !(3..=40).contains(&per_side) {
        return Err(Error::invalid(
            "grid",
            format!("dots per tile side must be 3..=40, got {per_side}"),
        ));
    }
    let [th, tw] = layout.wide_size();
    let n = layout.tile_px as f64;
    let pitch = n / per_side as f64;
    let radius = 0.18 * pitch;
    let mut centres = Vec::new();
    for i in 0..layout.lenses.len() {
        let mut tile = Vec::new();
        for r in 0..per_side {
            for c in 0..per_side {
                tile.push((
                    i as f64 * n + (c as f64 + 0.5) * pitch - 0.5,
                    (r as f64 + 0.5) * pitch - 0.5,
                ));
            }
        }
        centres.push(tile);
    }
    let mut img = Image::filled(1, th, tw, 1.0);
    for tile in &centres {
        for &(cx, cy) in tile {
            let (x0, x1) = (
                (cx - radius - 1.0).floor().max(0.0) as usize,
                ((cx + radius + 1.0).ceil() as usize).min(tw - 1),
            );
            let (y0, y1) = (
                (cy - radius - 1.0).floor().max(0.0) as usize,
                ((cy + radius + 1.0).ceil() as usize).min(th - 1),
            );
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let mut covered = 0;
                    for s in 0..16 {
                        let (px, py) = (
                            x as f64 + ((s % 4) as f64 + 0.5) / 4.0 - 0.5,
                            y as f64 + ((s / 4) as f64 + 0.5) / 4.0 - 0.5,
                        );
                        if (px - cx).powi(2) + (py - cy).powi(2) <= radius * radius {
                            covered += 1;
                        }
                    }
                    if covered > 0 {
                        img.set(0, y, x, 1.0 - covered as f32 / 16.0);
                    }
                }
            }
        }
    }
    Ok((img, centres))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_layout_fits_and_maps_back() {
        let layout = ArrayLayout::default();
        check_layout(&layout).unwrap();
        // A stitched pixel goes to the sensor and back to itself.
        for &(x, y) in &[(100.5, 200.0), (700.0, 30.0), (1400.0, 470.0)] {
            let (i, sx, sy) = nominal_sensor_position(&layout, x, y).unwrap();
            let (j, bx, by) = sensor_to_tile(&layout, sx, sy).unwrap();
            assert_eq!(i, j);
            assert!(
                (bx - x).abs() < 1e-6 && (by - y).abs() < 1e-6,
                "({x}, {y}) → ({bx}, {by})"
            );
        }
        let mut bad = layout.clone();
        bad.lenses[1].axis_px = [400.0, 380.0];
        assert!(check_layout(&bad).is_err());
    }
}
