//! The CPU reference stepper: the mass-spring model, readable, deterministic, in `f32` or `f64`.
//!
//! A substep computes every vertex's new state from the previous state only (a Jacobi sweep),
//! exactly as a GPU thread per vertex does with ping-pong buffers. The result is therefore
//! independent of the order vertices are visited in, and rayon can share the work out.

use rayon::prelude::*;

use crate::colliders::{Collider, Surface};
use crate::coloring::{VERTEX_COLOR_COUNT, vertex_color};
use crate::constraints::{contact_friction, project_spring, project_swept};
use crate::effects::Effect;
use crate::error::SimError;
use crate::forces::{
    add_spring_force, air_drag_force, contact_force, friction_force, friction_holds, gravity_force, grid_normal,
    integrate, stick, wind_force,
};
use crate::implicit::{ContactTerms, LinearisedStep, SpringTerms, conjugate_gradients};
use crate::integrator::{Integrator, XPBD_ITERATIONS};
use crate::model::ClothModel;
use crate::motion::{MotionOf, wind_velocity};
use crate::quantities::SceneQuantities;
use crate::real::{Mat3, Real, Vec3};
use crate::scene::Scene;
use crate::self_collision::{
    CellHash, MARGIN_ROUNDING, SelfCollisionQuantities, far_partners, for_each_near_partner, limit_speed,
    repulsion_force, self_contact_correction,
};
use crate::simulator::{ClothState, Diagnostics, Simulator, check_state_size};
use crate::solver::{LINE_SEARCH_SLOPES, LineSearchBracket, SolverIterations};
use crate::vbd::{self, LocalTerms, chebyshev_weight};

/// Vertices per rayon task: below this, splitting costs more than it saves.
const PARALLEL_CHUNK: usize = 512;

/// The effects a vertex's force evaluation tests, as the bits of a compile-time constant `E`
/// (bit `k` is `VARIANT_EFFECTS[k]`). Each combination is its own compiled function
/// ([`variant_force_and_stick`], [`variant_predicted_velocity`]), picked once per pass by
/// [`specialised!`] and called through a function pointer: the CPU's counterpart of the GPU's
/// specialization constants, so an absent effect is not even a branch in the per-vertex code.
/// (Only these small functions are instantiated 64 times; the loops around them are not, which
/// keeps the build time.) The other effects need no bit:
/// an absent spring kind has no springs in the list, absent contact no colliders, and the pins'
/// motion is computed once per substep.
const VARIANT_EFFECTS: [Effect; 6] =
    [Effect::Gravity, Effect::SpringDamping, Effect::AirDrag, Effect::Wind, Effect::MovingColliders, Effect::Friction];

/// The variant bits of an effect set (see [`VARIANT_EFFECTS`]).
fn variant_bits(effects: crate::effects::EffectSet) -> u16 {
    VARIANT_EFFECTS.iter().enumerate().filter(|(_, e)| effects.contains(**e)).map(|(k, _)| 1u16 << k).sum()
}

/// Evaluates `$call` with the constant `$E` equal to `$bits` (which is below 64): one compiled
/// copy of `$call` per combination of [`VARIANT_EFFECTS`].
macro_rules! specialised {
    ($bits:expr, $E:ident => $call:expr) => {
        specialised!(@arms $bits, $E, $call, [
            0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31
            32 33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59 60 61 62 63
        ])
    };
    (@arms $bits:expr, $E:ident, $call:expr, [$($n:literal)*]) => {
        match $bits {
            $( $n => {
                const $E: u16 = $n;
                $call
            } )*
            _ => unreachable!("variant bits have six bits"),
        }
    };
}

/// One end of a spring in precision `R`.
#[derive(Clone, Copy, Debug)]
struct End<R> {
    other: usize,
    kind: usize,
    rest_length: R,
}

/// One spring as an XPBD constraint (vertex `a` < `b`) in precision `R`.
#[derive(Clone, Copy, Debug)]
struct Constraint<R> {
    a: usize,
    b: usize,
    kind: usize,
    rest_length: R,
}

/// Parameters of one substep in precision `R` (the same values the GPU gets as `f32`).
#[derive(Clone, Debug)]
struct Params<R> {
    gravity: Vec3<R>,
    stiffness: [R; 3],
    damping: [R; 3],
    mass: R,
    dt: R,
    air_drag: R,
    colliders: Vec<Collider<R>>,
    /// Mean wind velocity, m/s; coefficient × area per vertex, N·s/m; gust amplitude and
    /// angular frequency, rad/s.
    wind: Vec3<R>,
    wind_coefficient_area: R,
    gust_amplitude: R,
    gust_omega: R,
    /// Each pin group's motion (group 0: `cloth.pin_motion`).
    pin_motions: Vec<MotionOf<R>>,
    /// Grid vertices along u and v (the wind's normals).
    nx: usize,
    ny: usize,
    /// The `SelfCollision` effect's parameters, when it is on.
    self_collision: Option<SelfParams<R>>,
}

/// The parameters of self-collision in precision `R` (see [`crate::self_collision`]).
#[derive(Clone, Copy, Debug)]
struct SelfParams<R> {
    /// Thickness `r`, m.
    thickness: R,
    /// `k_s`, N/m; `c_s`, N·s/m; `μ`.
    stiffness: R,
    damping: R,
    friction: R,
    /// `s_max`, m/s.
    max_speed: R,
    /// Grid spacing along u and v, m (the rest-distance filter).
    spacing: [R; 2],
    /// Buckets of the hash of the far partners (whose cell side is the thickness).
    buckets: u32,
}

impl<R: Real> SelfParams<R> {
    fn of(scene: &Scene) -> Option<Self> {
        if !scene.effects.contains(Effect::SelfCollision) {
            return None;
        }
        let q = SelfCollisionQuantities::of(scene);
        Some(Self {
            thickness: R::of(q.thickness),
            stiffness: R::of(q.stiffness),
            damping: R::of(q.damping),
            friction: R::of(q.friction),
            max_speed: R::of(q.max_speed),
            spacing: [R::of(q.spacing[0]), R::of(q.spacing[1])],
            buckets: q.buckets,
        })
    }

    /// The hash of the far partners at `positions`: cells of side `r` (and a rounding share
    /// more), so it lists every vertex closer than `r` to a point among the 27 cells around it.
    fn hash(&self, positions: &[Vec3<R>]) -> CellHash {
        CellHash::build(positions, self.thickness.to_f64_lossy() * (1.0 + MARGIN_ROUNDING), self.buckets)
    }
}

impl<R: Real> Params<R> {
    fn new(scene: &Scene) -> Self {
        let q = SceneQuantities::of(scene);
        let colliders = q.colliders.iter().map(Collider::of).collect();
        let of3 = |v: [f64; 3]| [R::of(v[0]), R::of(v[1]), R::of(v[2])];
        Self {
            gravity: Vec3::from_f64(q.gravity),
            stiffness: of3(q.stiffness),
            damping: of3(q.damping),
            mass: R::of(q.vertex_mass),
            dt: R::of(q.substep_dt),
            air_drag: R::of(q.air_drag),
            colliders,
            wind: Vec3::from_f64(q.wind_velocity),
            wind_coefficient_area: R::of(q.wind_coefficient_area),
            gust_amplitude: R::of(q.gust_amplitude),
            gust_omega: R::of(q.gust_omega),
            pin_motions: q.pin_motions.iter().map(MotionOf::of).collect(),
            nx: q.resolution[0] as usize,
            ny: q.resolution[1] as usize,
            self_collision: SelfParams::of(scene),
        }
    }

    /// Where a pin of group `group` at `x` at time `from` is at `to` (m), and its velocity there
    /// (m/s): `x` and zero without `MovingPins`.
    fn pin_move(&self, group: u8, x: Vec3<R>, from: R, to: R, moving: bool) -> (Vec3<R>, Vec3<R>) {
        if moving {
            let m = &self.pin_motions[group as usize];
            let x = m.carry(x, from, to);
            (x, m.point_velocity(x, to))
        } else {
            (x, Vec3::zero())
        }
    }

    /// The velocity of a pin of group `group` at `x` at time `t`, m/s (zero without
    /// `MovingPins`).
    fn pin_velocity(&self, group: u8, x: Vec3<R>, t: R, moving: bool) -> Vec3<R> {
        if moving { self.pin_motions[group as usize].point_velocity(x, t) } else { Vec3::zero() }
    }
}

/// The CPU reference simulator in precision `R` (`f32` or `f64`).
#[derive(Clone, Debug)]
pub struct ReferenceSimulator<R: Real> {
    scene: Scene,
    params: Params<R>,
    /// Start of each vertex's spring list in `ends`.
    first: Vec<usize>,
    ends: Vec<End<R>>,
    /// XPBD and backward Euler only (empty otherwise): every spring once, grouped by colour.
    constraints: Vec<Constraint<R>>,
    pinned: Vec<bool>,
    /// Each pinned vertex's group (its motion in `params.pin_motions`).
    pin_group: Vec<u8>,
    positions: Vec<Vec3<R>>,
    velocities: Vec<Vec3<R>>,
    next_positions: Vec<Vec3<R>>,
    next_velocities: Vec<Vec3<R>>,
    time_s: f64,
    /// The state's time in this precision, s, advanced as the GPU advances it (`velocity.w`):
    /// what moving pins, moving colliders and gusts see.
    clock: R,
    max_penetration: R,
    substeps_run: u64,
    /// Scratch reused from substep to substep, so a substep allocates nothing for
    /// self-collision: the positions at the substep's start (the speed limit's reference) and
    /// XPBD's averaged self-contact corrections.
    substep_start: Vec<Vec3<R>>,
    self_corrections: Vec<Vec3<R>>,
    /// What the implicit solvers spent since creation.
    solver_spent: SolverIterations,
    /// VBD only: the velocities at the start of the previous substep (its adaptive
    /// initialisation's acceleration).
    vbd_last_velocities: Vec<Vec3<R>>,
}

/// The `f32` reference: the oracle GPU results are compared with.
pub type CpuSimulator = ReferenceSimulator<f32>;
/// The `f64` reference: the high-precision oracle.
pub type CpuSimulatorF64 = ReferenceSimulator<f64>;

impl<R: Real> ReferenceSimulator<R> {
    /// Builds the simulator from an already built model (skips validation).
    pub fn from_model(model: &ClothModel) -> Self {
        let scene = model.scene.clone();
        let v0 = Vec3::from_f64(scene.cloth.initial_velocity);
        let positions: Vec<Vec3<R>> = model.grid.positions.iter().map(|p| Vec3::from_f64(*p)).collect();
        let velocities: Vec<Vec3<R>> = model.grid.pinned.iter().map(|&p| if p { Vec3::zero() } else { v0 }).collect();
        let mut simulator = Self {
            params: Params::new(&scene),
            first: model.adjacency.first.iter().map(|&f| f as usize).collect(),
            ends: model
                .adjacency
                .ends
                .iter()
                .map(|e| End { other: e.other as usize, kind: e.kind as usize, rest_length: R::of(e.rest_length) })
                .collect(),
            constraints: if matches!(scene.integrator, Integrator::Xpbd | Integrator::BackwardEuler) {
                model
                    .spring_colors()
                    .order
                    .iter()
                    .map(|&s| {
                        let s = &model.springs[s as usize];
                        Constraint {
                            a: s.a as usize,
                            b: s.b as usize,
                            kind: s.kind as usize,
                            rest_length: R::of(s.rest_length),
                        }
                    })
                    .collect()
            } else {
                Vec::new()
            },
            pinned: model.grid.pinned.clone(),
            pin_group: model.grid.pin_group.clone(),
            next_positions: positions.clone(),
            next_velocities: velocities.clone(),
            positions,
            velocities,
            time_s: 0.0,
            clock: R::zero(),
            max_penetration: R::zero(),
            substeps_run: 0,
            substep_start: Vec::new(),
            self_corrections: Vec::new(),
            solver_spent: SolverIterations::default(),
            vbd_last_velocities: Vec::new(),
            scene,
        };
        simulator.assume_free_fall();
        simulator
    }

    /// VBD's adaptive initialisation takes a state with no previous substep as in free fall: the
    /// velocities a substep of gravity before `v` (so a falling cloth starts from the full
    /// inertial prediction).
    fn assume_free_fall(&mut self) {
        let hg = self.params.gravity * self.params.dt;
        self.vbd_last_velocities = self.velocities.iter().map(|&v| v - hg).collect();
    }

    fn moving_pins(&self) -> bool {
        self.scene.effects.contains(Effect::MovingPins)
    }

    fn moving_colliders(&self) -> bool {
        self.scene.effects.contains(Effect::MovingColliders)
    }

    /// The read-only data of a force evaluation at state `(x, v)` and time `time` (with
    /// `SelfCollision`, the hash of `x`'s far partners). The per-vertex functions are the variant
    /// compiled for the scene's effects.
    fn context<'a>(&'a self, x: &'a [Vec3<R>], v: &'a [Vec3<R>], time: R) -> StepContext<'a, R> {
        let (force, predict) = specialised!(variant_bits(self.scene.effects), E => (
            variant_force_and_stick::<R, E> as ForceFn<R>,
            variant_predicted_velocity::<R, E> as PredictFn<R>,
        ));
        let hash = self.params.self_collision.map(|s| s.hash(x));
        StepContext { params: &self.params, force, predict, first: &self.first, ends: &self.ends, x, v, time, hash }
    }

    /// Positions in this precision, m.
    pub fn positions(&self) -> &[Vec3<R>] {
        &self.positions
    }

    /// Velocities in this precision, m/s.
    pub fn velocities(&self) -> &[Vec3<R>] {
        &self.velocities
    }

    /// Advances one substep of `Δt = scene.substep_dt()` with the scene's integrator.
    pub fn substep(&mut self) {
        // The speed limit applies at the substep's end (velocity Verlet applies it itself, its
        // drift before its second kick).
        let limited = self.params.self_collision.is_some() && self.scene.integrator != Integrator::VelocityVerlet;
        if limited {
            self.substep_start.clone_from(&self.positions);
        }
        match self.scene.integrator {
            Integrator::SemiImplicitEuler => self.euler_substep(),
            Integrator::VelocityVerlet => self.verlet_substep(),
            Integrator::RungeKutta4 => self.rk4_substep(),
            Integrator::Xpbd => self.xpbd_substep(),
            Integrator::BackwardEuler => self.backward_euler_substep(),
            Integrator::Vbd => self.vbd_substep(),
        }
        if let Some(s) = self.params.self_collision.as_ref().filter(|_| limited) {
            let (max_speed, dt, start) = (s.max_speed, self.params.dt, &self.substep_start);
            for i in (0..start.len()).filter(|&i| !self.pinned[i]) {
                (self.positions[i], self.velocities[i]) =
                    limit_speed(start[i], self.positions[i], self.velocities[i], max_speed, dt);
            }
        }
        let depth = self.deepest_penetration();
        if depth > self.max_penetration {
            self.max_penetration = depth;
        }
        self.substeps_run += 1;
        self.time_s += self.scene.substep_dt();
    }

    /// Forces on every vertex for the state `(x, v)` at time `time` (zero on pinned vertices);
    /// `friction_dt` is the step the friction's stopping term refers to.
    fn forces(&self, x: &[Vec3<R>], v: &[Vec3<R>], time: R, friction_dt: R) -> Vec<Vec3<R>> {
        self.forces_and_sticks(x, v, time, friction_dt).0
    }

    /// As [`Self::forces`], with, for each vertex, the normal of a contact whose friction holds it
    /// (static friction), if any.
    fn forces_and_sticks(
        &self,
        x: &[Vec3<R>],
        v: &[Vec3<R>],
        time: R,
        friction_dt: R,
    ) -> (Vec<Vec3<R>>, Vec<Option<Vec3<R>>>) {
        let ctx = self.context(x, v, time);
        let pinned = &self.pinned;
        (0..x.len())
            .into_par_iter()
            .with_min_len(PARALLEL_CHUNK)
            .map(|i| if pinned[i] { (Vec3::zero(), None) } else { ctx.vertex_force_and_stick(i, friction_dt) })
            .unzip()
    }

    /// `x + s·d` on free vertices (pinned ones keep `x`).
    fn offset(&self, x: &[Vec3<R>], d: &[Vec3<R>], s: R) -> Vec<Vec3<R>> {
        x.iter().zip(d).zip(&self.pinned).map(|((x, d), &p)| if p { *x } else { *x + *d * s }).collect()
    }

    /// Moves the pinned vertices of the state `(x, v)` from time `from` to `to` (`MovingPins`),
    /// each by its group's motion ([`MotionOf::carry`]) and at its velocity there; without it
    /// they keep `x` and a zero velocity.
    fn move_pins(&self, x: &mut [Vec3<R>], v: &mut [Vec3<R>], from: R, to: R) {
        let moving = self.moving_pins();
        for i in 0..x.len() {
            if self.pinned[i] {
                (x[i], v[i]) = self.params.pin_move(self.pin_group[i], x[i], from, to, moving);
            }
        }
    }

    /// Velocity Verlet: `v½ = v + ½Δt a(x, v)`, `x' = x + Δt v½`, `v' = v½ + ½Δt a(x', v½)`.
    fn verlet_substep(&mut self) {
        let p = &self.params;
        // The same operations, in the same order, as the GPU kernels' Verlet stages.
        let (h, half) = (p.dt, p.dt * R::of(0.5));
        let kick = half / p.mass;
        let (t, t1) = (self.clock, self.clock + h);
        let f1 = self.forces(&self.positions, &self.velocities, t, half);
        let mut v_half = self.offset(&self.velocities, &f1, kick);
        let mut x_new = self.offset(&self.positions, &v_half, h);
        if let Some(s) = &p.self_collision {
            // The speed limit on the drift, before the second kick reads the positions (as the
            // GPU's two stages do); on the velocity at the end.
            for (i, x) in x_new.iter_mut().enumerate().filter(|(i, _)| !self.pinned[*i]) {
                *x = limit_speed(self.positions[i], *x, Vec3::zero(), s.max_speed, h).0;
            }
        }
        self.move_pins(&mut x_new, &mut v_half, t, t1);
        let f2 = self.forces(&x_new, &v_half, t1, half);
        let mut v_new = self.offset(&v_half, &f2, kick);
        let moving = self.moving_pins();
        for i in (0..v_new.len()).filter(|&i| self.pinned[i]) {
            v_new[i] = self.params.pin_move(self.pin_group[i], x_new[i], t1, t1, moving).1;
        }
        if let Some(s) = &self.params.self_collision {
            for (v, _) in v_new.iter_mut().zip(&self.pinned).filter(|(_, pinned)| !**pinned) {
                *v = limit_speed(Vec3::zero(), Vec3::zero(), *v, s.max_speed, h).1;
            }
        }
        self.positions = x_new;
        self.velocities = v_new;
        self.clock = t1;
    }

    /// Classical fourth-order Runge–Kutta on `(x, v)` with `x' = v`, `v' = F(x, v)/m`; a vertex
    /// that friction holds at the last stage's state sticks (`forces::friction_holds`).
    fn rk4_substep(&mut self) {
        let p = &self.params;
        let (h, half, sixth) = (p.dt, p.dt * R::of(0.5), p.dt / R::of(6.0));
        let inv_m = R::one() / p.mass;
        // The stages' times, as the GPU computes them from the substep's start.
        let (t, t2, t4) = (self.clock, self.clock + half, self.clock + h);
        let (x, v) = (&self.positions, &self.velocities);
        let accel = |f: Vec<Vec3<R>>| -> Vec<Vec3<R>> { f.into_iter().map(|f| f * inv_m).collect() };
        // Stage k: position derivative = the stage's velocity, velocity derivative = a(stage).
        let a1 = accel(self.forces(x, v, t, h));
        let (mut x2, mut v2) = (self.offset(x, v, half), self.offset(v, &a1, half));
        self.move_pins(&mut x2, &mut v2, t, t2);
        let a2 = accel(self.forces(&x2, &v2, t2, h));
        let (mut x3, mut v3) = (self.offset(x, &v2, half), self.offset(v, &a2, half));
        // A pin's third-stage state is its second's (the GPU moves it from there by zero).
        for i in 0..x.len() {
            if self.pinned[i] {
                x3[i] = x2[i];
            }
        }
        self.move_pins(&mut x3, &mut v3, t2, t2);
        let a3 = accel(self.forces(&x3, &v3, t2, h));
        let (mut x4, mut v4) = (self.offset(x, &v3, h), self.offset(v, &a3, h));
        for i in 0..x.len() {
            if self.pinned[i] {
                x4[i] = x3[i];
            }
        }
        self.move_pins(&mut x4, &mut v4, t2, t4);
        let (f4, sticks) = self.forces_and_sticks(&x4, &v4, t4, h);
        let a4 = accel(f4);
        let two = R::of(2.0);
        let n = x.len();
        let mut x_new = Vec::with_capacity(n);
        let mut v_new = Vec::with_capacity(n);
        for i in 0..n {
            if self.pinned[i] {
                x_new.push(x4[i]);
                v_new.push(v4[i]);
            } else {
                let xi = x[i] + (v[i] + v2[i] * two + v3[i] * two + v4[i]) * sixth;
                let vi = v[i] + (a1[i] + a2[i] * two + a3[i] * two + a4[i]) * sixth;
                // Static friction at the substep's end (the last stage's state): stick exactly.
                let (xi, vi) = match sticks[i] {
                    Some(normal) => stick(xi, vi, x[i], normal),
                    None => (xi, vi),
                };
                x_new.push(xi);
                v_new.push(vi);
            }
        }
        self.positions = x_new;
        self.velocities = v_new;
        self.clock = t4;
    }

    /// XPBD (see [`Integrator::Xpbd`] and [`crate::constraints`]): predict with gravity, drag and
    /// wind, then [`XPBD_ITERATIONS`] times project every spring (colour by colour, in the order
    /// of [`crate::coloring`], so exactly what the GPU's one-dispatch-per-colour computes) and
    /// every collider (swept, where it is at the substep's end), apply friction to the contacts'
    /// displacements (relative to a moving collider), and derive the velocities `(x' − x)/Δt`.
    fn xpbd_substep(&mut self) {
        let p = &self.params;
        let (h, m) = (p.dt, p.mass);
        let w = R::one() / m;
        let effects = self.scene.effects;
        let (t, t1) = (self.clock, self.clock + h);
        let x0 = self.positions.clone();
        let moving_pins = self.moving_pins();
        let ctx = self.context(&x0, &self.velocities, t);
        let mut x: Vec<Vec3<R>> = (0..x0.len())
            .map(|i| {
                if self.pinned[i] {
                    p.pin_move(self.pin_group[i], x0[i], t, t1, moving_pins).0
                } else {
                    x0[i] + ctx.predicted_velocity(i) * h
                }
            })
            .collect();
        let inverse_mass = |i: usize| if self.pinned[i] { R::zero() } else { w };
        let moving = self.moving_colliders();
        // Each collider where it ends the substep, and how far it moved during it.
        let colliders: Vec<(Vec3<R>, Vec3<R>)> = p
            .colliders
            .iter()
            .map(|s| {
                let (start, _) = s.at(t, moving);
                let (end, _) = s.at(t1, moving);
                (end, end - start)
            })
            .collect();
        let mut corrections = std::mem::take(&mut self.self_corrections);
        let mut lambda = vec![R::zero(); self.constraints.len()];
        let mut normal_correction = vec![R::zero(); x.len()];
        for _ in 0..XPBD_ITERATIONS {
            // Colour by colour: the springs of one colour share no vertex, so this sequential
            // loop computes what the GPU computes with one invocation per spring.
            for (c, spring) in self.constraints.iter().enumerate() {
                let (a, b) = (spring.a, spring.b);
                let (mut x_a, mut x_b) = (x[a], x[b]);
                let k = p.stiffness[spring.kind];
                project_spring(
                    &mut x_a,
                    &mut x_b,
                    inverse_mass(a),
                    inverse_mass(b),
                    spring.rest_length,
                    k,
                    h,
                    &mut lambda[c],
                );
                (x[a], x[b]) = (x_a, x_b);
            }
            if let Some(s) = &p.self_collision {
                self.project_self_contacts(&mut x, &x0, s, &mut corrections);
            }
            for (i, xi) in x.iter_mut().enumerate() {
                if self.pinned[i] {
                    continue;
                }
                for (c, &(center, moved)) in p.colliders.iter().zip(&colliders) {
                    normal_correction[i] = normal_correction[i] + project_swept(xi, x0[i] + moved, c, center);
                }
            }
        }
        if effects.contains(Effect::Friction) {
            for (i, xi) in x.iter_mut().enumerate() {
                if self.pinned[i] || normal_correction[i] <= R::zero() {
                    continue;
                }
                for (c, &(center, moved)) in p.colliders.iter().zip(&colliders) {
                    // Off the collider friction does nothing: the normal only on it.
                    if c.distance(center, *xi) <= c.tolerance {
                        let surface = c.surface(center, *xi);
                        *xi = contact_friction(
                            *xi,
                            x0[i] + moved,
                            surface,
                            c.tolerance,
                            c.friction,
                            normal_correction[i],
                        );
                    }
                }
            }
        }
        let inv_h = R::one() / h;
        let v: Vec<Vec3<R>> = (0..x.len())
            .map(|i| {
                if self.pinned[i] {
                    p.pin_velocity(self.pin_group[i], x[i], t1, moving_pins)
                } else {
                    (x[i] - x0[i]) * inv_h
                }
            })
            .collect();
        self.positions = x;
        self.velocities = v;
        self.clock = t1;
        self.self_corrections = corrections;
    }

    /// XPBD's self-contacts, one Jacobi sweep: every free vertex's corrections
    /// ([`self_contact_correction`]) for its near partners, then its far partners (the
    /// forces' order), computed from `x` and averaged, then applied together (the GPU's one
    /// invocation per vertex).
    fn project_self_contacts(
        &self,
        x: &mut [Vec3<R>],
        x0: &[Vec3<R>],
        s: &SelfParams<R>,
        corrections: &mut Vec<Vec3<R>>,
    ) {
        let w = R::one() / self.params.mass;
        let (nx, ny) = (self.params.nx, self.params.ny);
        let pinned = &self.pinned;
        let positions: &[Vec3<R>] = x;
        let hash = s.hash(positions);
        let correction_of = |i: usize| {
            if pinned[i] {
                return Vec3::zero();
            }
            let (mut sum, mut count) = (Vec3::zero(), R::zero());
            let mut correct = |j: usize| {
                let w_j = if pinned[j] { R::zero() } else { w };
                if let Some(c) =
                    self_contact_correction(positions[i], positions[j], x0[i], x0[j], w, w_j, s.thickness, s.friction)
                {
                    sum += c;
                    count = count + R::one();
                }
            };
            for_each_near_partner(i, nx, ny, s.spacing, s.thickness, &mut correct);
            far_partners(&hash, positions, i, nx, s.spacing, s.thickness, s.thickness).into_iter().for_each(correct);
            if count > R::zero() { sum * (R::one() / count) } else { Vec3::zero() }
        };
        corrections.resize(x.len(), Vec3::zero());
        (corrections.par_iter_mut().enumerate().with_min_len(PARALLEL_CHUNK))
            .for_each(|(i, correction)| *correction = correction_of(i));
        for (xi, &c) in x.iter_mut().zip(corrections.iter()) {
            *xi += c;
        }
    }

    /// Backward Euler (see [`Integrator::BackwardEuler`] and [`crate::implicit`]): Newton
    /// iterations on `M (v' − v) = h f(x + h v', v')`. Iteration `k` linearises the forces about
    /// the state `(x̄, v̄)` (the substep's start first, Baraff and Witkin's step; then
    /// `(x + h v̄, v̄)`, at the substep's end time) and solves
    ///
    /// ```text
    /// (M + h C + h² K) Δ = h f(x̄, v̄) − h (K d_x + C d_v) − M (v̄ − v),   v̄ ← v̄ + Δ
    /// ```
    ///
    /// with `d_x = x + h v̄ − x̄` and `d_v = 0` on the free vertices (`h v` in the first iteration,
    /// zero after), and the pins' prescribed change on the pinned ones. `f` is the model's whole
    /// force ([`variant_force_and_stick`]); `K` and `C` hold the springs' blocks and the contacts'
    /// (the linearised part), while drag, wind, friction and self-collision enter through `f` at
    /// the iterate only. A vertex that friction holds at the end state loses its tangential velocity.
    fn backward_euler_substep(&mut self) {
        let p = &self.params;
        let (h, m, n) = (p.dt, p.mass, self.positions.len());
        let (t, t1) = (self.clock, self.clock + h);
        let solver = self.scene.solver;
        let (x0, v0) = (self.positions.clone(), self.velocities.clone());
        let (mut x_end, mut v_end) = (x0.clone(), v0.clone());
        self.move_pins(&mut x_end, &mut v_end, t, t1);
        let (mut x_bar, mut v_bar, mut time) = (x0.clone(), v0.clone(), t);
        let (mut dx, mut dv, mut drop) = (vec![Vec3::zero(); n], vec![Vec3::zero(); n], vec![Vec3::zero(); n]);
        // The largest right-hand side's norm of the substep's Newton iterations so far, N·s.
        let mut largest_b = R::zero();
        for _ in 0..solver.newton_iterations {
            let f = self.forces(&x_bar, &v_bar, time, h);
            let system = self.linearised_system(&x_bar, &v_bar, &x0, time);
            for i in 0..n {
                (dx[i], dv[i]) = if self.pinned[i] {
                    (x_end[i] - x_bar[i], v_end[i] - v_bar[i])
                } else {
                    (x0[i] + v_bar[i] * h - x_bar[i], Vec3::zero())
                };
            }
            system.force_drop(&dx, &dv, &mut drop);
            let mut b: Vec<Vec3<R>> = (0..n).map(|i| (f[i] - drop[i]) * h - (v_bar[i] - v0[i]) * m).collect();
            for c in &system.contacts {
                b[c.vertex] += c.pull * h;
            }
            let mut change = vec![Vec3::zero(); n];
            let report = conjugate_gradients(
                &system,
                &system.block_jacobi(),
                &b,
                &mut change,
                R::of(solver.cg_tolerance),
                largest_b,
                solver.cg_max_iterations,
            );
            largest_b = largest_b.max(report.rhs_norm);
            self.solver_spent.add_solve(report.iterations);
            let alpha = if solver.line_search {
                self.line_search_step(&change, &b, &v_bar, (&x_end, &v_end))
            } else {
                R::one()
            };
            (x_bar, v_bar) = self.newton_iterate(&change, alpha, &v_bar, (&x_end, &v_end));
            time = t1;
        }
        if self.scene.effects.contains(Effect::Friction) {
            // Static friction at the substep's end: the friction is a force of the iterate,
            // outside the linearisation, so a vertex it holds would otherwise creep. It keeps
            // its solved position and loses its tangential velocity. (Undoing its tangential
            // motion over the substep too, as RK4 does at its small steps, stretched the stiff
            // springs around a vertex landing at one substep a frame: `scenes/stiff_drape.ron` at
            // 16 × 16 with four Newton iterations peaked at 19.5 J from 8.8 J; the velocity alone
            // never rose above the start.)
            let (_, sticks) = self.forces_and_sticks(&x_bar, &v_bar, t1, h);
            for (i, normal) in sticks.into_iter().enumerate() {
                if let Some(normal) = normal.filter(|_| !self.pinned[i]) {
                    v_bar[i] = normal * v_bar[i].dot(normal);
                }
            }
        }
        self.positions = x_bar;
        self.velocities = v_bar;
        self.clock = t1;
    }

    /// The Newton iterate `v̄ + α Δ`, `x⁰ + h (v̄ + α Δ)` on the free vertices; the pinned ones at
    /// their prescribed end state `(x_end, v_end)`.
    fn newton_iterate(
        &self,
        change: &[Vec3<R>],
        alpha: R,
        v_bar: &[Vec3<R>],
        (x_end, v_end): (&[Vec3<R>], &[Vec3<R>]),
    ) -> (Vec<Vec3<R>>, Vec<Vec3<R>>) {
        let (h, x0) = (self.params.dt, &self.positions);
        (0..change.len())
            .map(|i| {
                if self.pinned[i] {
                    (x_end[i], v_end[i])
                } else {
                    let v = v_bar[i] + change[i] * alpha;
                    (x0[i] + v * h, v)
                }
            })
            .unzip()
    }

    /// The step length `α` of a Newton iteration's change `Δ` (solved from the right-hand side
    /// `b`) from the iterate `v̄`: a root of the incremental potential's slope along `Δ`,
    /// `g(α) = Δ·(M (v̄ + α Δ − v⁰) − h f(x⁰ + h (v̄ + α Δ), v̄ + α Δ))` (the gradient of
    /// backward Euler's incremental potential is `M (v' − v⁰) − h f`), with `g(0) = −Δ·b`. Where
    /// the full step does not overshoot the minimum (`g(0) < 0 < g(1)` fails), `α = 1`. Else
    /// regula falsi with the Illinois rule ([`LineSearchBracket`]): the bracket `[0, 1]` is cut at
    /// the secant's root `α = lo + (hi − lo) g(lo) / (g(lo) − g(hi))`, the slope measured there
    /// replaces the end of the bracket with its sign, and the last secant root is the step:
    /// [`LINE_SEARCH_SLOPES`] slopes measured in all, the first at the full step.
    ///
    /// Slopes rather than potentials: in f32 the potential's change along one step is lost in
    /// its rounding on a large grid, its slope is not; and the slope takes every force
    /// (friction, damping) as the substep applies it, where the potential would need them as
    /// dissipation potentials. Sums over the free vertices.
    fn line_search_step(
        &self,
        change: &[Vec3<R>],
        b: &[Vec3<R>],
        v_bar: &[Vec3<R>],
        (x_end, v_end): (&[Vec3<R>], &[Vec3<R>]),
    ) -> R {
        let (h, m) = (self.params.dt, self.params.mass);
        let v0 = &self.velocities;
        let free = || (0..change.len()).filter(|&i| !self.pinned[i]);
        let slope = |alpha: R| {
            let (x, v) = self.newton_iterate(change, alpha, v_bar, (x_end, v_end));
            let f = self.forces(&x, &v, self.clock + h, h);
            free().fold(R::zero(), |g, i| g + change[i].dot((v[i] - v0[i]) * m - f[i] * h))
        };
        let at_start = free().fold(R::zero(), |g, i| g - change[i].dot(b[i]));
        let at_full = slope(R::one());
        if !(at_start < R::zero() && at_full > R::zero()) {
            return R::one();
        }
        let mut bracket = LineSearchBracket::new(at_start, at_full);
        for _ in 1..LINE_SEARCH_SLOPES {
            bracket.cut(slope(bracket.secant()));
        }
        bracket.secant()
    }

    /// The linearised system of a backward-Euler iteration about `(x, v)` at time `time`: every
    /// spring's blocks (the damping ones with `SpringDamping`) and the blocks of each free
    /// vertex's contacts: `k_c n nᵀ`, and `c n nᵀ` while approaching.
    ///
    /// A contact is in the linearisation where the vertex is inside the collider at the iterate
    /// `x` or at the end position its velocity gives, `y = x⁰ + h v` (the same point after the
    /// first iteration, which linearises about the substep's start). Where `y` is inside, the
    /// penalty is linearised about `y`, with `y`'s normal and depth: its force enters as
    /// [`ContactTerms::pull`], `P(y) − P(x) + K_c (y − x)` (with `P(z) = −k_c min(φ(z), 0) n(z)`
    /// the penalty the model's force holds at `x`), so that the step's model of the contact is
    /// `P(y) − K_c (x' − y)` at the new position `x'`. A vertex whose free flight ends inside
    /// then lands where the penalty against its inertia puts it, as if the step had begun
    /// there. Linearised about a vertex still outside, the penalty is zero and its stiffness a
    /// brake: the vertex stops short of the surface by the ratio `1 + h² k_c / m` (36 at 256² on
    /// `scenes/drape.ron` at one substep a frame, whose landing frame then stored 42.8 J in the
    /// springs between braked vertices and those that reached the surface). Without the contact,
    /// the vertex would be stepped deep into the collider and pushed out by the next iteration
    /// with energy from nowhere.
    fn linearised_system(&self, x: &[Vec3<R>], v: &[Vec3<R>], x0: &[Vec3<R>], time: R) -> LinearisedStep<R> {
        let p = &self.params;
        let damped = self.scene.effects.contains(Effect::SpringDamping);
        let springs = self
            .constraints
            .iter()
            .map(|s| {
                let c = if damped { p.damping[s.kind] } else { R::zero() };
                SpringTerms::new(s.a, s.b, x[s.a], x[s.b], s.rest_length, p.stiffness[s.kind], c)
            })
            .collect();
        let moving = self.moving_colliders();
        let mut contacts = Vec::new();
        for c in &p.colliders {
            let (center, velocity) = c.at(time, moving);
            let penalty = |surface: Surface<R>| surface.normal * (-c.stiffness * surface.distance.min(R::zero()));
            for i in (0..x.len()).filter(|&i| !self.pinned[i]) {
                let y = x0[i] + v[i] * p.dt;
                let (at_iterate, at_end) = (c.surface(center, x[i]), c.surface(center, y));
                let ends_inside = at_end.distance < R::zero();
                if !(ends_inside || at_iterate.distance < R::zero()) {
                    continue;
                }
                let (at, surface) = if ends_inside { (y, at_end) } else { (x[i], at_iterate) };
                let n = surface.normal;
                let nn = Mat3::outer(n, n);
                let stiffness = nn * c.stiffness;
                let damping = if (v[i] - velocity).dot(n) < R::zero() { nn * c.damping } else { Mat3::zero() };
                let pull = penalty(surface) - penalty(at_iterate) + stiffness.mul_vec(at - x[i]);
                contacts.push(ContactTerms { vertex: i, stiffness, damping, pull });
            }
        }
        LinearisedStep {
            step: p.dt,
            masses: vec![p.mass; x.len()],
            free: self.pinned.iter().map(|&pinned| !pinned).collect(),
            springs,
            contacts,
        }
    }

    /// Vertex Block Descent (see [`Integrator::Vbd`] and [`crate::vbd`]): the inertial prediction
    /// `y = x + h v + h² F_ext/m` (gravity, drag and wind as XPBD predicts them, plus
    /// self-collision's repulsion at the substep's start), then the solver's sweeps, colour by
    /// colour, of every free vertex's Newton step on its [`LocalTerms`] (inertia, springs with
    /// their damping, the colliders where they end the substep, with friction), each optionally
    /// extrapolated by Chebyshev's weight; finally `v = (x − x⁰)/h`.
    fn vbd_substep(&mut self) {
        let p = &self.params;
        let (h, m) = (p.dt, p.mass);
        let (t, t1) = (self.clock, self.clock + h);
        let solver = self.scene.solver;
        let moving_pins = self.moving_pins();
        let x0 = self.positions.clone();
        let ctx = self.context(&x0, &self.velocities, t);
        let self_push = h * h / m;
        let y: Vec<Vec3<R>> = (0..x0.len())
            .into_par_iter()
            .with_min_len(PARALLEL_CHUNK)
            .map(|i| {
                if self.pinned[i] {
                    return p.pin_move(self.pin_group[i], x0[i], t, t1, moving_pins).0;
                }
                let mut y = x0[i] + ctx.predicted_velocity(i) * h;
                if let (Some(hash), Some(s)) = (&ctx.hash, &p.self_collision) {
                    y += ctx.self_collision_force(hash, s, i, h) * self_push;
                }
                y
            })
            .collect();
        let colliders: Vec<(Vec3<R>, Vec3<R>)> =
            p.colliders.iter().map(|c| c.at(t1, self.moving_colliders())).collect();
        let friction = self.scene.effects.contains(Effect::Friction);
        let damped = self.scene.effects.contains(Effect::SpringDamping);
        let (nx, first, ends, pinned) = (p.nx, &self.first, &self.ends, &self.pinned);
        let local_terms = |x: &[Vec3<R>], i: usize| {
            let mut terms = LocalTerms::inertia(x[i], y[i], m, h);
            for end in &ends[first[i]..first[i + 1]] {
                let j = end.other;
                let c = if damped { p.damping[end.kind] } else { R::zero() };
                terms.add_spring((x[i], x0[i]), (x[j], x0[j]), end.rest_length, p.stiffness[end.kind], c, h);
            }
            for (c, &(center, velocity)) in p.colliders.iter().zip(&colliders) {
                if c.distance(center, x[i]) < R::of(vbd::CONTACT_BAND) {
                    let mu = if friction { c.friction } else { R::zero() };
                    let surface = c.surface(center, x[i]);
                    terms.add_contact((x[i], x0[i]), surface, velocity, c.stiffness, c.damping, mu, h);
                }
            }
            terms
        };
        let stop_at_surfaces = |from: Vec3<R>, moved: Vec3<R>| {
            let mut fraction = R::one();
            for (c, &(center, _)) in p.colliders.iter().zip(&colliders) {
                if let Some(s) = vbd::surface_fraction(c.distance(center, from), c.distance(center, moved)) {
                    fraction = fraction.min(s);
                }
            }
            if fraction < R::one() { from + (moved - from) * fraction } else { moved }
        };
        let local_step = |x: &[Vec3<R>], i: usize| {
            // A step from outside a collider into it stops at its surface (vbd::surface_fraction).
            stop_at_surfaces(x[i], local_terms(x, i).step(x[i]))
        };
        // The vertices of each colour (free ones only).
        let colours: Vec<Vec<usize>> = (0..VERTEX_COLOR_COUNT)
            .map(|colour| {
                (0..x0.len())
                    .filter(|&i| !pinned[i] && vertex_color((i % nx) as u32, (i / nx) as u32) == colour)
                    .collect()
            })
            .collect();
        // The initial guess: the adaptive initialisation of Chen et al., the inertial step plus the
        // part of gravity the vertex's last substep actually showed.
        let gravity = p.gravity;
        let mut x: Vec<Vec3<R>> = (0..x0.len())
            .map(|i| {
                if pinned[i] {
                    y[i]
                } else {
                    let acceleration = (self.velocities[i] - self.vbd_last_velocities[i]) * (R::one() / h);
                    x0[i] + self.velocities[i] * h + gravity * (vbd::gravity_share(acceleration, gravity) * h * h)
                }
            })
            .collect();
        // Chebyshev's history: each vertex's iterate one and two sweeps back.
        let (mut previous, mut before) = (x.clone(), x.clone());
        let rho = R::of(solver.chebyshev_rho);
        let mut moved = Vec::new();
        // The multigrid coarse correction (crate::multigrid): the substep's Newton system
        // linearised where the sweeps left the vertices, solved on aggregates of the grid.
        let coarse_correction = |x: &mut Vec<Vec3<R>>| {
            let ny = x.len() / nx;
            let free: Vec<bool> = pinned.iter().map(|&p| !p).collect();
            let terms: Vec<LocalTerms<R>> =
                (0..x.len()).into_par_iter().with_min_len(PARALLEL_CHUNK).map(|i| local_terms(x, i)).collect();
            let couplings: Vec<Vec<(usize, crate::real::Mat3<R>)>> = (0..x.len())
                .into_par_iter()
                .with_min_len(PARALLEL_CHUNK)
                .map(|i| {
                    ends[first[i]..first[i + 1]]
                        .iter()
                        .map(|end| {
                            let j = end.other;
                            let c = if damped { p.damping[end.kind] } else { R::zero() };
                            let k = crate::forces::spring_stiffness_block(
                                x[i],
                                x[j],
                                end.rest_length,
                                p.stiffness[end.kind],
                            ) + crate::forces::spring_damping_block(x[i], x[j], c) * (R::one() / h);
                            (j, k * (-R::one()))
                        })
                        .collect()
                })
                .collect();
            let diagonal: Vec<_> = terms.iter().map(|t| t.hessian).collect();
            let gradient: Vec<_> = terms.iter().map(|t| t.gradient).collect();
            let (level, b) = crate::multigrid::first_level(nx, ny, &free, &diagonal, &couplings, &gradient);
            let levels = crate::multigrid::hierarchy(level);
            let e = crate::multigrid::v_cycle(&levels, 0, &b);
            let alpha = crate::multigrid::step_length(&levels[0], &e, &b);
            let cnx = levels[0].nx;
            for i in 0..x.len() {
                if free[i] {
                    let d = e[(i % nx) / 2 + ((i / nx) / 2) * cnx] * alpha;
                    x[i] = stop_at_surfaces(x[i], x[i] + d);
                }
            }
        };
        for sweep in 1..=solver.vbd_iterations {
            let every = solver.vbd_multigrid_every;
            if every > 0 && (sweep - 1) % every == 0 {
                coarse_correction(&mut x);
            }
            let omega = chebyshev_weight(sweep, rho);
            for vertices in &colours {
                // A colour's vertices share no spring: each step reads only other colours' positions.
                (vertices.par_iter().with_min_len(PARALLEL_CHUNK).map(|&i| local_step(&x, i)))
                    .collect_into_vec(&mut moved);
                for (&i, &xi) in vertices.iter().zip(&moved) {
                    if rho > R::zero() {
                        x[i] = before[i] + (xi - before[i]) * omega;
                        before[i] = previous[i];
                        previous[i] = x[i];
                    } else {
                        x[i] = xi;
                    }
                }
            }
        }
        self.solver_spent.vbd += u64::from(solver.vbd_iterations);
        self.vbd_last_velocities.clone_from(&self.velocities);
        let inv_h = R::one() / h;
        self.velocities = (0..x.len())
            .map(|i| {
                if pinned[i] {
                    p.pin_velocity(self.pin_group[i], x[i], t1, moving_pins)
                } else {
                    (x[i] - x0[i]) * inv_h
                }
            })
            .collect();
        self.positions = x;
        self.clock = t1;
    }

    /// The model's semi-implicit Euler: every vertex from the previous state (Jacobi sweep).
    fn euler_substep(&mut self) {
        let (t, t1) = (self.clock, self.clock + self.params.dt);
        let moving_pins = self.moving_pins();
        let mut next_positions = std::mem::take(&mut self.next_positions);
        let mut next_velocities = std::mem::take(&mut self.next_velocities);
        let ctx = self.context(&self.positions, &self.velocities, t);
        let (x, pinned, groups, params) = (&self.positions, &self.pinned, &self.pin_group, &self.params);
        next_positions
            .par_iter_mut()
            .zip(next_velocities.par_iter_mut())
            .enumerate()
            .with_min_len(PARALLEL_CHUNK)
            .for_each(|(i, (x_new, v_new))| {
                (*x_new, *v_new) =
                    if pinned[i] { params.pin_move(groups[i], x[i], t, t1, moving_pins) } else { ctx.vertex_update(i) };
            });
        self.next_positions = next_positions;
        self.next_velocities = next_velocities;
        std::mem::swap(&mut self.positions, &mut self.next_positions);
        std::mem::swap(&mut self.velocities, &mut self.next_velocities);
        self.clock = t1;
    }

    /// Deepest penetration of any vertex into any collider right now, `max −φ`, m (0 when none).
    pub fn deepest_penetration(&self) -> R {
        let moving = self.moving_colliders();
        let colliders: Vec<(&Collider<R>, Vec3<R>)> =
            self.params.colliders.iter().map(|c| (c, c.at(self.clock, moving).0)).collect();
        if colliders.is_empty() {
            return R::zero();
        }
        self.positions
            .par_iter()
            .with_min_len(PARALLEL_CHUNK)
            .map(|&x| colliders.iter().map(|(c, center)| -c.distance(*center, x)).fold(R::zero(), R::max))
            .reduce(R::zero, R::max)
    }
}

/// A vertex's resultant force and the normal of a contact whose friction holds it, compiled for
/// one combination of [`VARIANT_EFFECTS`] (see [`variant_force_and_stick`]).
type ForceFn<R> = fn(&StepContext<'_, R>, usize, R) -> (Vec3<R>, Option<Vec3<R>>);
/// XPBD's predicted velocity of a vertex, compiled for one combination of [`VARIANT_EFFECTS`].
type PredictFn<R> = fn(&StepContext<'_, R>, usize) -> Vec3<R>;

/// Read-only data of one force evaluation, and the variant of the per-vertex functions compiled
/// for the scene's effects.
struct StepContext<'a, R: Real> {
    params: &'a Params<R>,
    force: ForceFn<R>,
    predict: PredictFn<R>,
    first: &'a [usize],
    ends: &'a [End<R>],
    x: &'a [Vec3<R>],
    v: &'a [Vec3<R>],
    /// Time of the state `(x, v)`, s.
    time: R,
    /// The hash of the far partners of `x`, with `SelfCollision`.
    hash: Option<CellHash>,
}

/// The effects of variant `E` as constants (bit `k` of `E` is `VARIANT_EFFECTS[k]`).
struct Variant<const E: u16>;

impl<const E: u16> Variant<E> {
    const GRAVITY: bool = E & 1 != 0;
    const SPRING_DAMPING: bool = E & 2 != 0;
    const AIR_DRAG: bool = E & 4 != 0;
    const WIND: bool = E & 8 != 0;
    const MOVING_COLLIDERS: bool = E & 16 != 0;
    const FRICTION: bool = E & 32 != 0;
}

impl<R: Real> StepContext<'_, R> {
    /// New position and velocity of free vertex `i` under semi-implicit Euler: sum the forces,
    /// then integrate.
    fn vertex_update(&self, i: usize) -> (Vec3<R>, Vec3<R>) {
        let p = self.params;
        integrate(self.x[i], self.v[i], self.vertex_force(i, p.dt), p.mass, p.dt)
    }

    /// The wind on vertex `i` moving at `v`, N (the `Wind` effect).
    fn wind_force(&self, i: usize, v: Vec3<R>) -> Vec3<R> {
        let p = self.params;
        let normal = grid_normal(self.x, i, p.nx, p.ny);
        let wind = wind_velocity(p.wind, p.gust_amplitude, p.gust_omega, self.time);
        wind_force(normal, v, wind, p.wind_coefficient_area)
    }

    /// The self-collision force on free vertex `i`, N: the repulsion of every near partner, row
    /// by row, then of every far partner, in increasing index ([`crate::self_collision`]; the
    /// GPU's order).
    fn self_collision_force(&self, hash: &CellHash, s: &SelfParams<R>, i: usize, friction_dt: R) -> Vec3<R> {
        let p = self.params;
        let (x, v) = (self.x[i], self.v[i]);
        let mut force = Vec3::zero();
        let mut repel = |j: usize| {
            force += repulsion_force(
                x,
                self.x[j],
                v,
                self.v[j],
                s.thickness,
                s.stiffness,
                s.damping,
                s.friction,
                p.mass,
                friction_dt,
            );
        };
        for_each_near_partner(i, p.nx, p.ny, s.spacing, s.thickness, &mut repel);
        far_partners(hash, self.x, i, p.nx, s.spacing, s.thickness, s.thickness).into_iter().for_each(repel);
        force
    }

    /// XPBD's prediction of free vertex `i`'s velocity over the substep, m/s (see
    /// [`variant_predicted_velocity`]).
    fn predicted_velocity(&self, i: usize) -> Vec3<R> {
        (self.predict)(self, i)
    }

    /// The resultant force on free vertex `i`, N (see [`variant_force_and_stick`]).
    fn vertex_force(&self, i: usize, friction_dt: R) -> Vec3<R> {
        self.vertex_force_and_stick(i, friction_dt).0
    }

    /// [`Self::vertex_force`], with the normal of a contact whose friction holds the vertex, if any.
    fn vertex_force_and_stick(&self, i: usize, friction_dt: R) -> (Vec3<R>, Option<Vec3<R>>) {
        (self.force)(self, i, friction_dt)
    }
}

/// XPBD's prediction of free vertex `i`'s velocity over the substep, m/s: the external forces
/// only (gravity, drag, wind), `v + Δt F/m`, each added in the GPU's order, for the effects of
/// variant `E`.
fn variant_predicted_velocity<R: Real, const E: u16>(ctx: &StepContext<'_, R>, i: usize) -> Vec3<R> {
    let p = ctx.params;
    let (h, m) = (p.dt, p.mass);
    let mut v = ctx.v[i];
    if Variant::<E>::GRAVITY {
        v += p.gravity * h;
    }
    if Variant::<E>::AIR_DRAG {
        v += air_drag_force(m, p.air_drag, v) * (h / m);
    }
    if Variant::<E>::WIND {
        v += ctx.wind_force(i, v) * (h / m);
    }
    v
}

/// The resultant force on free vertex `i`, N: gravity, springs, drag, wind, then contact and
/// friction (computed from the others), for the effects of variant `E`; with the normal of a
/// contact whose friction holds the vertex, if any. `friction_dt` is the step the friction's
/// stopping term refers to.
fn variant_force_and_stick<R: Real, const E: u16>(
    ctx: &StepContext<'_, R>,
    i: usize,
    friction_dt: R,
) -> (Vec3<R>, Option<Vec3<R>>) {
    let p = ctx.params;
    let (x, v) = (ctx.x[i], ctx.v[i]);
    let mut force = Vec3::zero();
    if Variant::<E>::GRAVITY {
        force += gravity_force(p.mass, p.gravity);
    }
    for end in &ctx.ends[ctx.first[i]..ctx.first[i + 1]] {
        let j = end.other;
        let damping = if Variant::<E>::SPRING_DAMPING { p.damping[end.kind] } else { R::zero() };
        add_spring_force(&mut force, x, ctx.x[j], v, ctx.v[j], end.rest_length, p.stiffness[end.kind], damping);
    }
    if Variant::<E>::AIR_DRAG {
        force += air_drag_force(p.mass, p.air_drag, v);
    }
    if Variant::<E>::WIND {
        force += ctx.wind_force(i, v);
    }
    if let (Some(hash), Some(s)) = (&ctx.hash, &p.self_collision) {
        force += ctx.self_collision_force(hash, s, i, friction_dt);
    }
    // Contact and friction: R_o, the resultant of the other forces, is the force so far.
    // Against a moving collider they act on the velocity relative to it.
    let other_forces = force;
    let mut stuck = None;
    for s in &p.colliders {
        let (center, collider_velocity) = s.at(ctx.time, Variant::<E>::MOVING_COLLIDERS);
        let v_rel = v - collider_velocity;
        // The normal only for a vertex inside (φ < 0): the common case, outside, needs the
        // distance alone, as on the GPU.
        if s.distance(center, x) >= R::zero() {
            continue;
        }
        if let Some(contact) = contact_force(v_rel, s.surface(center, x), s.stiffness, s.damping) {
            force += contact.force;
            if Variant::<E>::FRICTION {
                force += friction_force(other_forces, v_rel, contact.normal, p.mass, friction_dt, s.friction);
                if stuck.is_none()
                    && friction_holds(other_forces, v_rel, contact.normal, p.mass, friction_dt, s.friction)
                {
                    stuck = Some(contact.normal);
                }
            }
        }
    }
    (force, stuck)
}

impl<R: Real> ReferenceSimulator<R> {
    fn name() -> &'static str {
        if size_of::<R>() == 4 { "cpu" } else { "cpu-f64" }
    }
}

impl<R: Real> Simulator for ReferenceSimulator<R> {
    fn new(scene: &Scene) -> Result<Self, SimError> {
        scene.validate()?;
        Ok(Self::from_model(&ClothModel::new(scene)))
    }

    fn backend_name(&self) -> &'static str {
        Self::name()
    }

    fn adapter_name(&self) -> String {
        let precision = if size_of::<R>() == 4 { "f32" } else { "f64" };
        format!("CPU reference ({precision}, {} rayon threads)", rayon::current_num_threads())
    }

    fn scene(&self) -> &Scene {
        &self.scene
    }

    fn advance(&mut self, frames: u32) -> Result<(), SimError> {
        let substeps = self.scene.substeps_per_frame() as u64 * frames as u64;
        for _ in 0..substeps {
            self.substep();
        }
        Ok(())
    }

    fn update_parameters(&mut self, scene: &Scene) -> Result<(), SimError> {
        if let Some(what) = self.scene.rebuild_reason(scene) {
            return Err(SimError::RebuildRequired { what });
        }
        scene.validate()?;
        self.params = Params::new(scene);
        self.scene = scene.clone();
        Ok(())
    }

    fn read_state(&mut self) -> Result<ClothState, SimError> {
        let to_f32 = |v: &Vec3<R>| {
            let [x, y, z] = v.to_f64();
            [x as f32, y as f32, z as f32]
        };
        Ok(ClothState {
            time_s: self.time_s,
            positions: self.positions.iter().map(to_f32).collect(),
            velocities: self.velocities.iter().map(to_f32).collect(),
        })
    }

    fn write_state(&mut self, state: &ClothState) -> Result<(), SimError> {
        check_state_size(self.positions.len(), state)?;
        self.positions = state.positions.iter().map(|p| Vec3::from_f32(*p)).collect();
        self.velocities = state.velocities.iter().map(|v| Vec3::from_f32(*v)).collect();
        self.time_s = state.time_s;
        self.clock = R::of(state.time_s as f32 as f64);
        self.assume_free_fall();
        Ok(())
    }

    fn diagnostics(&mut self) -> Result<Diagnostics, SimError> {
        Ok(Diagnostics {
            max_penetration_m: self.max_penetration.to_f64_lossy(),
            substeps_run: self.substeps_run,
            candidate_lists: None,
            solver: self
                .scene
                .integrator
                .is_implicit()
                .then_some(SolverIterations { substeps: self.substeps_run, ..self.solver_spent }),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::EffectSet;

    /// The constants of variant `E`, in [`VARIANT_EFFECTS`] order.
    fn flags<const E: u16>() -> [bool; 6] {
        [
            Variant::<E>::GRAVITY,
            Variant::<E>::SPRING_DAMPING,
            Variant::<E>::AIR_DRAG,
            Variant::<E>::WIND,
            Variant::<E>::MOVING_COLLIDERS,
            Variant::<E>::FRICTION,
        ]
    }

    #[test]
    fn each_variant_constant_is_the_bit_of_its_effect() {
        assert_eq!(
            VARIANT_EFFECTS,
            [
                Effect::Gravity,
                Effect::SpringDamping,
                Effect::AirDrag,
                Effect::Wind,
                Effect::MovingColliders,
                Effect::Friction
            ]
        );
        let on = |k: usize| variant_bits(EffectSet::empty().with(VARIANT_EFFECTS[k]));
        assert_eq!((0..6).map(on).collect::<Vec<_>>(), [1, 2, 4, 8, 16, 32]);
        let single = [flags::<1>(), flags::<2>(), flags::<4>(), flags::<8>(), flags::<16>(), flags::<32>()];
        for (k, f) in single.iter().enumerate() {
            assert_eq!(*f, std::array::from_fn(|j| j == k), "bit {k}");
        }
        assert_eq!(flags::<0>(), [false; 6]);
        assert_eq!(flags::<63>(), [true; 6]);
        assert_eq!(variant_bits(EffectSet::from_iter(Effect::ALL)), 63);
    }
}
