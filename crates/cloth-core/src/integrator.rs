//! Time integrators: how a substep turns forces into new velocities and positions.
//!
//! * [`Integrator::SemiImplicitEuler`], the brief's: `v += Δt F(x, v)/m; x += Δt v`. First order,
//!   symplectic, stable for `Δt < 2/ω` (less with damping).
//! * [`Integrator::VelocityVerlet`]: kick–drift–kick, `v½ = v + ½Δt a(x, v)`, `x' = x + Δt v½`,
//!   `v' = v½ + ½Δt a(x', v½)`. Second order for conservative forces, symplectic, same stability
//!   limit `2/ω`; velocity-dependent forces (damping, friction, drag) are evaluated with the
//!   velocity at hand, which keeps second order for them only approximately. The GPU backends run
//!   it as two dispatches per substep (the shaders' `STAGE` constant: kick and drift, then kick).
//! * [`Integrator::RungeKutta4`]: the classical four-stage method on `(x, v)`. Fourth order, not
//!   symplectic (it slowly dissipates energy), stable for `Δt < 2√2/ω` on an undamped spring.
//!   CPU reference only; the GPU backends refuse it with [`crate::SimError::Unsupported`].
//!
//! Contact and friction keep the brief's meaning under every integrator: they are forces of the
//! state each stage evaluates. The friction's "stop within this step" term uses the step its
//! velocity update spans: `Δt` for Euler and RK4, `½Δt` for each half kick of Verlet.

use serde::{Deserialize, Serialize};

/// Which time integrator a scene uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Integrator {
    /// The brief's semi-implicit (symplectic) Euler. Default.
    #[default]
    SemiImplicitEuler,
    /// Velocity Verlet (kick–drift–kick).
    VelocityVerlet,
    /// Classical fourth-order Runge–Kutta.
    RungeKutta4,
}

impl Integrator {
    /// Every integrator.
    pub const ALL: [Integrator; 3] =
        [Integrator::SemiImplicitEuler, Integrator::VelocityVerlet, Integrator::RungeKutta4];

    /// Order of accuracy of the positions for smooth, conservative forces.
    pub fn order(self) -> u32 {
        match self {
            Integrator::SemiImplicitEuler => 1,
            Integrator::VelocityVerlet => 2,
            Integrator::RungeKutta4 => 4,
        }
    }

    /// `ω Δt` at the edge of stability on an undamped harmonic oscillator.
    pub fn stability_limit(self) -> f64 {
        match self {
            Integrator::SemiImplicitEuler | Integrator::VelocityVerlet => 2.0,
            // RK4's stability region reaches ±2√2 along the imaginary axis (undamped springs).
            Integrator::RungeKutta4 => 2.0 * std::f64::consts::SQRT_2,
        }
    }

    /// Force evaluations per substep.
    pub fn stages(self) -> u32 {
        match self {
            Integrator::SemiImplicitEuler => 1,
            Integrator::VelocityVerlet => 2,
            Integrator::RungeKutta4 => 4,
        }
    }

    /// Short name for tables and file names.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::SemiImplicitEuler => "euler",
            Integrator::VelocityVerlet => "verlet",
            Integrator::RungeKutta4 => "rk4",
        }
    }
}
