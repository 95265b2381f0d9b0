//! Stats panel: cost per frame, throughput, stability margin, energy and penetration over time.

use cloth_core::{Scene, stability};
use eframe::egui;
use egui_plot::{Legend, Line, Plot, PlotPoints};

use crate::stats::Stats;

pub fn show(ui: &mut egui::Ui, stats: &Stats, scene: &Scene) {
    ui.label(format!("{:.3} ms per frame on the backend (advance + read-back)", stats.ms_per_frame));
    ui.label(format!("{:.3e} vertex-substeps per second", stats.vertex_substeps_per_s));
    let margin = stability::stability_margin(scene);
    let color = if margin > 1.0 {
        egui::Color32::from_rgb(220, 40, 40)
    } else if margin > 0.8 {
        egui::Color32::from_rgb(230, 160, 30)
    } else {
        egui::Color32::from_rgb(60, 170, 80)
    };
    ui.label("Stability margin (substep / largest stable substep)");
    ui.add(egui::ProgressBar::new((margin / 1.5).min(1.0) as f32).fill(color).text(format!("{margin:.2}")));
    if margin > 1.0 {
        ui.colored_label(color, "above 1: the simulation will blow up — raise the substeps");
    }
    let series = |f: fn(&crate::stats::Sample) -> f64| -> PlotPoints<'static> {
        stats.samples.iter().map(|s| [s.time_s, f(s)]).collect::<Vec<_>>().into()
    };
    ui.label("Energy (J) against simulated time (s)");
    Plot::new("energy").height(150.0).legend(Legend::default()).show(ui, |plot| {
        plot.line(Line::new("kinetic", series(|s| s.kinetic_j)));
        plot.line(Line::new("elastic", series(|s| s.elastic_j)));
    });
    match stats.samples.back().and_then(|s| s.self_intersections) {
        Some(0) => ui.label("Self-intersections: none (no cloth edge passes through a cloth triangle)"),
        Some(n) => ui.colored_label(
            egui::Color32::from_rgb(220, 40, 40),
            format!("Self-intersections: {n} edge-triangle crossings (the crossed triangles in red, drawn through the cloth)"),
        ),
        None => ui.label(format!(
            "Self-intersections: not counted (above {} vertices, where cloth run --json counts them, or the \
             cloth is torn across itself)",
            crate::app::MAX_COUNTED_VERTICES
        )),
    }
    .on_hover_text("Counted exactly on the last sampled state (docs/model.md, Self-intersections)");
    solver_iterations(ui, stats);
    if let Some(lists) = stats.samples.back().and_then(|s| s.candidate_lists) {
        let share = if lists.checks > 0 { 100.0 * lists.rebuilds as f64 / lists.checks as f64 } else { 0.0 };
        ui.label(format!(
            "Self-collision's candidate lists: checked {} times, rebuilt {} ({share:.0}%); {} lists overflowed",
            lists.checks, lists.rebuilds, lists.overflowed_lists
        ))
        .on_hover_text(
            "The GPU rebuilds its lists of far partners when the cloth's parts may have moved against each other by \
             more than the margin (docs/model.md, Self-collision)",
        );
    }
    if stats.samples.iter().any(|s| s.self_intersections.is_some()) {
        Plot::new("self-intersections").height(80.0).show(ui, |plot| {
            plot.line(Line::new("crossings", series(|s| s.self_intersections.map_or(f64::NAN, |n| n as f64))));
        });
    }
    ui.label("Max penetration (mm) against simulated time (s)");
    Plot::new("penetration").height(120.0).show(ui, |plot| {
        plot.line(Line::new("max penetration", series(|s| s.max_penetration_m * 1e3)));
    });
}

/// What the implicit integrator's solver spent between the last two samples, per substep: the
/// difference of the two readings (the backend counts since its creation).
fn solver_iterations(ui: &mut egui::Ui, stats: &crate::stats::Stats) {
    let mut recent = stats.samples.iter().rev().filter_map(|s| s.solver);
    let (Some(last), Some(before)) = (recent.next(), recent.next()) else { return };
    if last.substeps <= before.substeps {
        return;
    }
    let spent = last.since(&before);
    let per = |n: u64| n as f64 / spent.substeps as f64;
    let text = if spent.vbd > 0 {
        format!("Solver: {:.0} VBD sweeps a substep", per(spent.vbd))
    } else {
        format!(
            "Solver: {:.1} Newton and {:.1} CG iterations a substep ({:.1} a solve; at most {} in one solve so far)",
            per(spent.newton),
            per(spent.cg),
            spent.cg_per_solve(),
            last.cg_most
        )
    };
    ui.label(text).on_hover_text(
        "The implicit integrators' iterations over the last frame shown (the scene's solver field sets their limits; \
         docs/model.md, The implicit integrators)",
    );
}
