//! Cloth panel: resolution and size (rebuild), mass, pins.

use cloth_core::scene::{Corner, Edge, Mass, Pin};
use eframe::egui;

use super::{PanelContext, problems_for, quantity, vector};

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>) {
    let cloth = &mut ctx.scene.cloth;
    ui.horizontal(|ui| {
        ui.label("Resolution");
        ui.add(egui::DragValue::new(&mut cloth.resolution[0]).range(0..=4096).suffix(" nx"));
        ui.label("×");
        ui.add(egui::DragValue::new(&mut cloth.resolution[1]).range(0..=4096).suffix(" ny"));
        ui.label("vertices (rebuilds)");
    });
    problems_for(ui, ctx.problems, "cloth.resolution");
    ui.horizontal(|ui| {
        ui.label("Size");
        ui.add(egui::DragValue::new(&mut cloth.size[0]).speed(0.01).suffix(" m"));
        ui.label("×");
        ui.add(egui::DragValue::new(&mut cloth.size[1]).speed(0.01).suffix(" m"));
        ui.label("(rebuilds)");
    });
    problems_for(ui, ctx.problems, "cloth.size");
    vector(ui, "Centre", &mut cloth.center, "m", 0.01);
    problems_for(ui, ctx.problems, "cloth.center");
    let (mut total, mut value) = match cloth.mass {
        Mass::Total(m) => (true, m),
        Mass::PerVertex(m) => (false, m),
    };
    ui.horizontal(|ui| {
        ui.selectable_value(&mut total, true, "Total mass");
        ui.selectable_value(&mut total, false, "Per vertex");
    });
    quantity(ui, "Mass", &mut value, "kg", 0.001);
    cloth.mass = if total { Mass::Total(value) } else { Mass::PerVertex(value) };
    problems_for(ui, ctx.problems, "cloth.mass");
    ui.label("Pins (rebuilds)");
    ui.horizontal_wrapped(|ui| {
        for (label, pin) in [
            ("top-left", Pin::Corner(Corner::TopLeft)),
            ("top-right", Pin::Corner(Corner::TopRight)),
            ("bottom-left", Pin::Corner(Corner::BottomLeft)),
            ("bottom-right", Pin::Corner(Corner::BottomRight)),
            ("top edge", Pin::Edge(Edge::Top)),
        ] {
            let mut on = cloth.pins.contains(&pin);
            if ui.checkbox(&mut on, label).changed() {
                if on {
                    cloth.pins.push(pin);
                } else {
                    cloth.pins.retain(|p| *p != pin);
                }
            }
        }
    });
    let others = cloth.pins.iter().filter(|p| matches!(p, Pin::Vertex(_) | Pin::GridPoint(..))).count();
    if others > 0 {
        ui.label(format!("+ {others} pinned vertices from the scene file"));
    }
    problems_for(ui, ctx.problems, "cloth.pins");
}
