//! `cloth figure`: the pictures of docs/model.md, drawn from the model's own code: the 12-spring
//! stencil from `SpringKind::stencil`, and the friction decomposition from
//! `forces::friction_force` on an example contact.

use std::path::Path;

use anyhow::{Result, anyhow};
use cloth_core::SpringKind;
use cloth_core::forces::friction_force;
use cloth_core::real::Vec3;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Which picture.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Figure {
    /// The springs of one vertex: structural, shear and bend.
    Stencil,
    /// The friction force from the resultant of the other forces on a contact.
    Friction,
}

type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;

/// Writes `figure` as SVG to `path`.
pub fn write(figure: Figure, path: &Path) -> Result<()> {
    crate::study::plot::register_font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (640, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        match figure {
            Figure::Stencil => stencil(&root),
            Figure::Friction => friction(&root),
        }
        .map_err(|e| anyhow!("cannot draw {}: {e}", path.display()))?;
        root.present().map_err(|e| anyhow!("cannot draw {}: {e}", path.display()))?;
    }
    Ok(cloth_backends::output::write_atomically(path, text.as_bytes())?)
}

fn text(area: &Area, label: &str, at: (i32, i32), size: u32, color: &RGBColor) -> Result<(), String> {
    let style = ("sans-serif", size).into_font().color(color);
    area.draw(&Text::new(label.to_string(), at, style)).map_err(|e| e.to_string())
}

fn arrow(area: &Area, from: (i32, i32), to: (i32, i32), color: &RGBColor) -> Result<(), String> {
    let (dx, dy) = ((to.0 - from.0) as f64, (to.1 - from.1) as f64);
    let length = (dx * dx + dy * dy).sqrt().max(1.0);
    let (ux, uy) = (dx / length, dy / length);
    let head = |side: f64| (to.0 - (12.0 * ux - 6.0 * side * uy) as i32, to.1 - (12.0 * uy + 6.0 * side * ux) as i32);
    let style = color.stroke_width(3);
    area.draw(&PathElement::new(vec![from, to], style)).map_err(|e| e.to_string())?;
    area.draw(&Polygon::new(vec![to, head(1.0), head(-1.0)], color.filled())).map_err(|e| e.to_string())
}

/// A 5 × 5 patch of the grid around vertex (i, j), with the springs of (i, j): each stencil
/// offset and its opposite, one colour a kind.
fn stencil(area: &Area) -> Result<(), String> {
    let cell = 80;
    let at = |di: i64, dj: i64| (320 + di as i32 * cell, 250 - dj as i32 * cell);
    let colors = [RGBColor(40, 90, 200), RGBColor(220, 120, 20), RGBColor(30, 150, 70)];
    for (kind, color) in SpringKind::ALL.iter().zip(&colors) {
        for &(di, dj) in kind.stencil() {
            for sign in [1, -1] {
                let style = color.stroke_width(if *kind == SpringKind::Bend { 2 } else { 4 });
                let (a, b) = (at(0, 0), at(sign * di, sign * dj));
                // Bend springs run over the structural ones: drawn offset a little to show both.
                let shift = if *kind == SpringKind::Bend { 6 } else { 0 };
                let path = vec![
                    (a.0 + shift * (dj != 0) as i32, a.1 + shift * (di != 0) as i32),
                    (b.0 + shift * (dj != 0) as i32, b.1 + shift * (di != 0) as i32),
                ];
                area.draw(&PathElement::new(path, style)).map_err(|e| e.to_string())?;
            }
        }
    }
    for di in -2..=2 {
        for dj in -2..=2 {
            let center = (di, dj) == (0, 0);
            let dot =
                Circle::new(at(di, dj), if center { 9 } else { 6 }, if center { RED.filled() } else { BLACK.filled() });
            area.draw(&dot).map_err(|e| e.to_string())?;
        }
    }
    text(area, "vertex (i, j) and its 12 springs", (20, 15), 22, &BLACK)?;
    for (k, (kind, color)) in SpringKind::ALL.iter().zip(&colors).enumerate() {
        let offsets: Vec<String> = kind.stencil().iter().map(|(di, dj)| format!("±({di}, {dj})")).collect();
        text(area, &format!("{}: {}", kind.name(), offsets.join(", ")), (20, 410 + 22 * k as i32), 18, color)?;
    }
    Ok(())
}

/// A vertex on a sphere's surface (normal up) pushed down and sideways by the other forces: the
/// decomposition into normal and tangential parts and the friction `friction_force` returns, at
/// rest (v = 0), for c_f = 0.5.
fn friction(area: &Area) -> Result<(), String> {
    let (origin, scale) = ((300, 200), 42.0);
    let to_px = |v: Vec3<f64>| (origin.0 + (v.x * scale) as i32, origin.1 - (v.y * scale) as i32);
    let (normal, r_o, c_f) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(3.0, -4.0, 0.0), 0.5);
    let r_on = normal * r_o.dot(normal);
    let r_ot = r_o - r_on;
    let f_f = friction_force(r_o, Vec3::zero(), normal, 1.0, 1e-3, c_f);
    let (gray, black) = (RGBColor(120, 120, 120), BLACK);
    area.draw(&PathElement::new(vec![(40, origin.1), (600, origin.1)], gray.stroke_width(2)))
        .map_err(|e| e.to_string())?;
    text(area, "surface (tangent plane)", (440, origin.1 + 8), 16, &gray)?;
    arrow(area, origin, to_px(normal * 2.0), &black)?;
    text(area, "1_n", (origin.0 + 8, to_px(normal * 2.0).1), 18, &black)?;
    let colors = [RGBColor(200, 40, 40), RGBColor(40, 90, 200), RGBColor(30, 150, 70), RGBColor(140, 60, 170)];
    let vectors = [
        (r_o, "R_o (the other forces)"),
        (r_on, "R_on = (R_o·1_n) 1_n"),
        (r_ot, "R_ot = R_o − R_on"),
        (f_f, "F_f = −min(|R_ot|, c_f |R_on|) 1_t"),
    ];
    for (k, ((v, label), color)) in vectors.iter().zip(&colors).enumerate() {
        arrow(area, origin, to_px(*v), color)?;
        text(area, label, (20, 20 + 24 * k as i32), 18, color)?;
    }
    let caption = format!(
        "c_f = {c_f}: |R_ot| = {:.1} > c_f |R_on| = {:.1}, so the vertex slides",
        r_ot.length(),
        c_f * r_on.length()
    );
    text(area, &caption, (20, 440), 16, &black)
}
