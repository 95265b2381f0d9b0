//! Energies of a cloth state, J: used by tests, the CLI summary and the inspector's plots.

use crate::effects::Effect;
use crate::model::ClothModel;
use crate::simulator::ClothState;
use crate::springs::SpringKind;

/// Energy split by kind, J.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// `Σ ½ m |v|²` over the free vertices.
    pub kinetic: f64,
    /// `Σ ½ k (L − L0)²` over the springs, per kind `[structural, shear, bend]`.
    pub elastic: [f64; 3],
    /// `−Σ m g · x` over the free vertices (zero at the origin).
    pub gravitational: f64,
    /// `Σ ½ k_c d²` over the vertices inside a collider (`d = −φ`, see [`crate::colliders`]).
    pub contact: f64,
}

impl Energy {
    /// Sum of every term.
    pub fn total(&self) -> f64 {
        self.kinetic + self.elastic.iter().sum::<f64>() + self.gravitational + self.contact
    }

    /// Computes the energies of a state of `model` (in `f64`).
    pub fn of(model: &ClothModel, state: &ClothState) -> Self {
        let scene = &model.scene;
        let m = scene.vertex_mass();
        let p = |i: usize| state.positions[i].map(f64::from);
        let mut e = Energy::default();
        for (i, v) in state.velocities.iter().enumerate() {
            if model.grid.pinned[i] {
                continue;
            }
            let v = v.map(f64::from);
            e.kinetic += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            if scene.effects.contains(Effect::Gravity) {
                let x = p(i);
                e.gravitational -= m * (scene.gravity[0] * x[0] + scene.gravity[1] * x[1] + scene.gravity[2] * x[2]);
            }
        }
        for s in &model.springs {
            let k = match s.kind {
                SpringKind::Structural => scene.springs.structural.stiffness,
                SpringKind::Shear => scene.springs.shear.stiffness,
                SpringKind::Bend => scene.springs.bend.stiffness,
            };
            let stretch = crate::springs::distance(p(s.a as usize), p(s.b as usize)) - s.rest_length;
            e.elastic[s.kind as usize] += 0.5 * k * stretch * stretch;
        }
        if scene.effects.contains(Effect::Contact) {
            let moving = scene.effects.contains(Effect::MovingColliders);
            for spec in &scene.colliders {
                let collider = crate::colliders::Collider::<f64>::of(spec);
                // Where the collider is at the state's time.
                let (center, _) = collider.at(state.time_s, moving);
                for i in 0..state.positions.len() {
                    let depth = -collider.distance(center, crate::real::Vec3::from_f64(p(i)));
                    if depth > 0.0 {
                        e.contact += 0.5 * spec.stiffness * depth * depth;
                    }
                }
            }
        }
        e
    }
}
