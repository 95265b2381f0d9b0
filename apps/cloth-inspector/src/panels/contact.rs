//! Contact panel: the colliders (each kind's shape, k_c, c_f, damping, motion), adding and
//! removing them, which one shift-drag moves, and contact and friction on/off.

use cloth_core::Effect;
use cloth_core::colliders::{ColliderKind, ColliderSpec, MAX_COLLIDERS, Shape};
use cloth_core::scene::SphereSpec;
use eframe::egui;

use super::{PanelContext, motion, problems_for, quantity, vector};

/// A new collider of `kind`, placed under the cloth's start.
fn new_collider(kind: ColliderKind, cloth_center: [f64; 3]) -> ColliderSpec {
    let [x, y, z] = cloth_center;
    let below = [x, y - 0.8, z];
    let shape = match kind {
        ColliderKind::Sphere => return SphereSpec { center: below, ..Default::default() }.into(),
        ColliderKind::Plane => Shape::Plane { normal: [0.0, 1.0, 0.0], offset: 0.0 },
        ColliderKind::Capsule => Shape::Capsule { a: [x - 0.6, y - 0.8, z], b: [x + 0.6, y - 0.8, z], radius: 0.15 },
        ColliderKind::Box => Shape::Box {
            center: below,
            half_extents: [0.5, 0.25, 0.5],
            axis: [0.0, 1.0, 0.0],
            angle: 0.0,
            rounding: 0.0,
        },
        // The torus the project ships (its path as seen from the repository's root).
        ColliderKind::Mesh => Shape::Mesh {
            file: "scenes/meshes/torus.obj".into(),
            center: below,
            scale: 1.0,
            axis: [0.0, 1.0, 0.0],
            angle: 0.0,
            cells: 32,
        },
    };
    ColliderSpec::of(shape)
}

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>, dragged: &mut usize) {
    for (effect, label) in [(Effect::Contact, "contact"), (Effect::Friction, "friction")] {
        let mut on = ctx.scene.effects.contains(effect);
        if ui.checkbox(&mut on, format!("{label} (on/off rebuilds)")).changed() {
            ctx.scene.effects.set(effect, on);
        }
    }
    problems_for(ui, ctx.problems, "effects");
    let moving = ctx.scene.effects.contains(Effect::MovingColliders);
    let mut remove = None;
    for (k, collider) in ctx.scene.colliders.iter_mut().enumerate() {
        ui.separator();
        ui.horizontal(|ui| {
            ui.strong(format!("Collider {k}: {}", collider.kind().name()));
            ui.radio_value(dragged, k, "shift-drag moves it");
            if ui.small_button("remove (rebuilds)").clicked() {
                remove = Some(k);
            }
        });
        match &mut collider.shape {
            Shape::Sphere { center, radius } => {
                vector(ui, "centre", center, "m", 0.01);
                quantity(ui, "radius", radius, "m", 0.005);
            }
            Shape::Plane { normal, offset } => {
                vector(ui, "normal (outward)", normal, "", 0.01);
                quantity(ui, "offset along the normal", offset, "m", 0.01);
            }
            Shape::Capsule { a, b, radius } => {
                vector(ui, "end a", a, "m", 0.01);
                vector(ui, "end b", b, "m", 0.01);
                quantity(ui, "radius", radius, "m", 0.005);
            }
            Shape::Box { center, half_extents, axis, angle, rounding } => {
                vector(ui, "centre", center, "m", 0.01);
                vector(ui, "half extents", half_extents, "m", 0.01);
                vector(ui, "rotation axis", axis, "", 0.01);
                quantity(ui, "rotation angle", angle, "°", 0.5);
                quantity(ui, "edge rounding", rounding, "m", 0.005);
            }
            Shape::Mesh { file, center, scale, axis, angle, cells } => {
                ui.horizontal(|ui| {
                    ui.label("OBJ file (rebuilds)");
                    ui.text_edit_singleline(file);
                });
                vector(ui, "origin at", center, "m", 0.01);
                quantity(ui, "scale", scale, "m per unit", 0.01);
                vector(ui, "rotation axis", axis, "", 0.01);
                quantity(ui, "rotation angle", angle, "°", 0.5);
                ui.horizontal(|ui| {
                    ui.add(egui::DragValue::new(cells).range(2..=cloth_core::mesh::MAX_CELLS));
                    ui.label("distance-field cells along the mesh (rebuilds)");
                });
            }
        }
        quantity(ui, "contact stiffness k_c", &mut collider.stiffness, "N/m", 10.0);
        quantity(ui, "friction c_f", &mut collider.friction, "", 0.01);
        quantity(ui, "contact damping", &mut collider.damping, "N·s/m", 0.01);
        if moving {
            motion(ui, "motion from the start", &mut collider.motion);
        }
        problems_for(ui, ctx.problems, &format!("colliders[{k}]"));
    }
    if let Some(k) = remove {
        ctx.scene.colliders.remove(k);
    }
    *dragged = (*dragged).min(ctx.scene.colliders.len().saturating_sub(1));
    ui.horizontal_wrapped(|ui| {
        ui.label("Add (rebuilds):");
        let room = ctx.scene.colliders.len() < MAX_COLLIDERS;
        for kind in ColliderKind::ALL {
            let button = ui
                .add_enabled(room, egui::Button::new(kind.name()))
                .on_disabled_hover_text(format!("a scene holds at most {MAX_COLLIDERS} colliders"));
            if button.clicked() {
                ctx.scene.colliders.push(new_collider(kind, ctx.scene.cloth.center));
            }
        }
    });
    ui.label(egui::RichText::new("Shift-drag in the view moves the chosen collider.").weak());
    if !moving {
        ui.label(egui::RichText::new("Turn on MovingColliders (Effects) to animate a collider.").weak());
    }
}
