//! Every quantity a simulation derives from its scene, computed once, in `f64`.
//!
//! The CPU reference converts these to its precision (`reference.rs`) and the GPU backends to
//! their `f32` uniform (`cloth_gpu::layout::GpuSimParams`): neither derives a mass, an area, a
//! rest length or a wind coefficient of its own, so they cannot disagree on one.

use crate::colliders::ColliderSpec;
use crate::effects::Effect;
use crate::scene::{Motion, Scene};
use crate::springs::rest_length;

/// What one substep of a scene needs, derived from the scene. Units as in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneQuantities {
    /// Grid vertices `[nx, ny]`.
    pub resolution: [u32; 2],
    /// Gravitational acceleration `g`, m/s².
    pub gravity: [f64; 3],
    /// Spring stiffness `k`, N/m, by `SpringKind` (structural, shear, bend).
    pub stiffness: [f64; 3],
    /// Spring damping `c_d`, N·s/m, by `SpringKind`.
    pub damping: [f64; 3],
    /// Mass of each vertex `m`, kg.
    pub vertex_mass: f64,
    /// Substep length `Δt = frame_dt / substeps`, s.
    pub substep_dt: f64,
    /// Air-drag rate `γ`, 1/s.
    pub air_drag: f64,
    /// Rest lengths, m: structural along u (`Δu`), along v (`Δv`), shear (`√(Δu² + Δv²)`); the
    /// bend springs' are exactly twice the structural ones.
    pub rest_lengths: [f64; 3],
    /// Mean wind velocity `w`, m/s.
    pub wind_velocity: [f64; 3],
    /// The wind coefficient times the area a vertex stands for, `c A = c Δu Δv`, N·s/m.
    pub wind_coefficient_area: f64,
    /// Relative amplitude of the gusts.
    pub gust_amplitude: f64,
    /// Angular frequency of the gusts `2π / period`, rad/s.
    pub gust_omega: f64,
    /// How each pin group moves (`cloth.pin_motion`, then `cloth.pin_groups` in order).
    pub pin_motions: Vec<Motion>,
    /// The colliders the cloth meets: the scene's with `Contact`, none without.
    pub colliders: Vec<ColliderSpec>,
}

impl SceneQuantities {
    /// The quantities of `scene`.
    pub fn of(scene: &Scene) -> Self {
        let s = &scene.springs;
        let [nx, ny] = scene.cloth.resolution;
        let [size_u, size_v] = scene.cloth.size;
        let spacing = scene.cloth.spacing();
        let rest = |di, dj| rest_length(spacing, di, dj);
        let w = &scene.wind;
        Self {
            resolution: [nx, ny],
            gravity: scene.gravity,
            stiffness: [s.structural.stiffness, s.shear.stiffness, s.bend.stiffness],
            damping: [s.structural.damping, s.shear.damping, s.bend.damping],
            vertex_mass: scene.vertex_mass(),
            substep_dt: scene.substep_dt(),
            air_drag: scene.air_drag,
            rest_lengths: [rest(1, 0), rest(0, 1), rest(1, 1)],
            wind_velocity: w.velocity,
            wind_coefficient_area: w.coefficient * size_u / (nx.max(2) - 1) as f64 * size_v / (ny.max(2) - 1) as f64,
            gust_amplitude: w.gust_amplitude,
            gust_omega: 2.0 * std::f64::consts::PI / w.gust_period,
            pin_motions: std::iter::once(scene.cloth.pin_motion)
                .chain(scene.cloth.pin_groups.iter().map(|g| g.motion))
                .collect(),
            colliders: if scene.effects.contains(Effect::Contact) { scene.colliders.clone() } else { Vec::new() },
        }
    }
}
