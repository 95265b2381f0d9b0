//! Scenes: everything a simulation needs, loaded from RON files.
//!
//! Every field has a unit and a default; a field left out of a RON file takes the
//! default shown here. `Scene::default()` is the default scene: a 32 × 32 cloth
//! falling onto a sphere and draping over it.
//!
//! ```ron
//! Scene(
//!     name: "drape",
//!     cloth: (resolution: (32, 32), size: (2.0, 2.0), center: (0.0, 1.8, 0.0)),
//!     colliders: [(shape: Sphere(center: (0.0, 1.0, 0.0), radius: 0.5))],
//! )
//! ```
//!
//! A `spheres: [...]` list (each `(center, radius, stiffness, friction, damping, motion)`) is
//! also read: its spheres become the first colliders. A scene that names neither `spheres` nor
//! `colliders` has the default sphere; one that names either has exactly what it lists.
//!
//! Loading never panics: [`Scene::from_ron_str`] returns a [`SceneError`](crate::SceneError) that names the
//! line and column of a syntax error, or every validation problem at once.

use serde::{Deserialize, Serialize};

use crate::colliders::ColliderSpec;
use crate::effects::EffectSet;
use crate::self_collision::SelfCollisionSpec;
use crate::solver::SolverSpec;

/// A complete simulation set-up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "SceneFile")]
pub struct Scene {
    /// Short name shown in the tools. Default `"drape"`.
    pub name: String,
    /// One sentence saying what the scene shows.
    pub description: String,
    /// The cloth: resolution, size, placement, mass and pins.
    pub cloth: ClothSpec,
    /// Stiffness and damping of each spring kind.
    pub springs: SpringSpecs,
    /// What the cloth collides with (see [`crate::colliders`]). Default: one sphere of radius
    /// 0.5 m centred at (0, 1, 0).
    pub colliders: Vec<ColliderSpec>,
    /// Gravitational acceleration `g`, m/s². Default `(0, -9.81, 0)`.
    pub gravity: [f64; 3],
    /// Air-drag rate `γ`, 1/s, for the `AirDrag` effect: `F = -m γ v`. Default 0.5.
    pub air_drag: f64,
    /// The wind of the `Wind` effect. Default: still air.
    pub wind: WindSpec,
    /// Time stepping: frame length, substeps per frame, run length.
    pub time: TimeSpec,
    /// Time integrator. Default `SemiImplicitEuler` (the model's); `VelocityVerlet`,
    /// `RungeKutta4`, `Xpbd`, `BackwardEuler` and `Vbd` run on every backend too (see [`crate::integrator`]).
    pub integrator: crate::integrator::Integrator,
    /// The effects this scene simulates. Default: the mass-spring model's (everything but air drag and the driven effects).
    pub effects: EffectSet,
    /// The parameters of the `SelfCollision` effect (see [`crate::self_collision`]). Default:
    /// [`SelfCollisionSpec::default`].
    pub self_collision: SelfCollisionSpec,
    /// The implicit integrators' solver settings (see [`crate::solver`]). Default:
    /// [`SolverSpec::default`].
    pub solver: SolverSpec,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            name: "drape".into(),
            description: "A cloth falls onto a sphere and drapes over it (the default scene).".into(),
            cloth: ClothSpec::default(),
            springs: SpringSpecs::default(),
            colliders: vec![ColliderSpec::default()],
            gravity: [0.0, -9.81, 0.0],
            air_drag: 0.5,
            wind: WindSpec::default(),
            time: TimeSpec::default(),
            integrator: crate::integrator::Integrator::default(),
            effects: EffectSet::default(),
            self_collision: SelfCollisionSpec::default(),
            solver: SolverSpec::default(),
        }
    }
}

/// A scene as a RON file writes it: [`Scene`]'s fields, with the `spheres` list as well as
/// `colliders`, and neither defaulting to the default sphere when the other is given.
#[derive(Deserialize)]
#[serde(rename = "Scene", default, deny_unknown_fields)]
struct SceneFile {
    name: String,
    description: String,
    cloth: ClothSpec,
    springs: SpringSpecs,
    #[serde(deserialize_with = "given")]
    spheres: Option<Vec<SphereSpec>>,
    #[serde(deserialize_with = "given")]
    colliders: Option<Vec<ColliderSpec>>,
    gravity: [f64; 3],
    air_drag: f64,
    wind: WindSpec,
    time: TimeSpec,
    integrator: crate::integrator::Integrator,
    effects: EffectSet,
    self_collision: SelfCollisionSpec,
    solver: SolverSpec,
}

/// A field that is present (RON writes a list, not `Some(list)`).
fn given<'de, D: serde::Deserializer<'de>, T: Deserialize<'de>>(d: D) -> Result<Option<T>, D::Error> {
    T::deserialize(d).map(Some)
}

impl Default for SceneFile {
    fn default() -> Self {
        let s = Scene::default();
        Self {
            name: s.name,
            description: s.description,
            cloth: s.cloth,
            springs: s.springs,
            spheres: None,
            colliders: None,
            gravity: s.gravity,
            air_drag: s.air_drag,
            wind: s.wind,
            time: s.time,
            integrator: s.integrator,
            effects: s.effects,
            self_collision: s.self_collision,
            solver: s.solver,
        }
    }
}

impl From<SceneFile> for Scene {
    fn from(f: SceneFile) -> Self {
        let colliders = match (f.spheres, f.colliders) {
            (None, None) => Scene::default().colliders,
            (spheres, colliders) => {
                spheres.into_iter().flatten().map(ColliderSpec::from).chain(colliders.into_iter().flatten()).collect()
            }
        };
        Self {
            name: f.name,
            description: f.description,
            cloth: f.cloth,
            springs: f.springs,
            colliders,
            gravity: f.gravity,
            air_drag: f.air_drag,
            wind: f.wind,
            time: f.time,
            integrator: f.integrator,
            effects: f.effects,
            self_collision: f.self_collision,
            solver: f.solver,
        }
    }
}

/// The cloth: an `nx × ny` grid of point masses spanning a rectangle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClothSpec {
    /// Vertices along the two sides, `(nx, ny)`; each at least 2. Default `(32, 32)`.
    /// This is the cloth's number of vertices: edit it here or with
    /// `cloth run --grid NXxNY`.
    pub resolution: [u32; 2],
    /// Physical size of the rectangle along its two sides, m. Default `(2.0, 2.0)`.
    pub size: [f64; 2],
    /// Position of the rectangle's centre, m. Default `(0, 1.8, 0)`.
    pub center: [f64; 3],
    /// Orientation of the rectangle. Default `Horizontal`.
    pub orientation: Orientation,
    /// Mass of the point masses. Default `Total(0.5)` kg.
    pub mass: Mass,
    /// Vertices held fixed in space. Default: none.
    pub pins: Vec<Pin>,
    /// Velocity every free vertex starts with, m/s. Default `(0, 0, 0)`.
    pub initial_velocity: [f64; 3],
    /// How the pins of `pins` move, for the `MovingPins` effect (each from where it started).
    /// Default: no motion.
    pub pin_motion: Motion,
    /// More pins, in groups that each follow their own motion (for `MovingPins`): `pins` with
    /// `pin_motion` are the first group, these the next, at most [`MAX_PIN_GROUPS`] in all. A
    /// vertex listed by several groups follows the last of them. Default: none.
    pub pin_groups: Vec<PinGroup>,
    /// A wave the cloth starts folded into (its rest shape stays the flat rectangle). Default:
    /// none (amplitude 0).
    pub ripple: Ripple,
}

/// A starting shape: every vertex is moved along the cloth's normal by
/// `amplitude · sin(2π b / wavelength)`, `b` its distance from row `j = 0` along `v` (m), so the
/// cloth starts in waves across its rows, the springs stretched as the waves need.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Ripple {
    /// Amplitude, m. Default 0 (flat).
    pub amplitude: f64,
    /// Wavelength along `v`, m (> 0). Default 0.4.
    pub wavelength: f64,
}

impl Default for Ripple {
    fn default() -> Self {
        Self { amplitude: 0.0, wavelength: 0.4 }
    }
}

impl ClothSpec {
    /// Distance between grid neighbours along u and along v, m: `size / (resolution − 1)`.
    pub fn spacing(&self) -> [f64; 2] {
        let [nx, ny] = self.resolution;
        [self.size[0] / (nx.max(2) - 1) as f64, self.size[1] / (ny.max(2) - 1) as f64]
    }
}

impl Default for ClothSpec {
    fn default() -> Self {
        Self {
            resolution: [32, 32],
            size: [2.0, 2.0],
            center: [0.0, 1.8, 0.0],
            orientation: Orientation::Horizontal,
            mass: Mass::Total(0.5),
            pins: Vec::new(),
            initial_velocity: [0.0; 3],
            pin_motion: Motion::default(),
            pin_groups: Vec::new(),
            ripple: Ripple::default(),
        }
    }
}

/// How many pin groups a cloth may have: `cloth.pins` and up to three `cloth.pin_groups` (the
/// GPU parameters hold this many motions).
pub const MAX_PIN_GROUPS: usize = 4;

/// Pins that move together: every vertex of `pins` follows `motion` from where it started.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PinGroup {
    /// The group's vertices.
    pub pins: Vec<Pin>,
    /// How they move, for the `MovingPins` effect. Default: no motion.
    pub motion: Motion,
}

/// How the cloth rectangle is oriented. Vertex `(i, j)` sits at
/// `center + (i/(nx-1) - ½)·size_u·u + (j/(ny-1) - ½)·size_v·v`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Orientation {
    /// Lying flat: `u = +X`, `v = -Z` (the normal is +Y).
    Horizontal,
    /// Standing up: `u = +X`, `v = +Y` (the normal is +Z); row `j = ny-1` is the top.
    Vertical,
    /// Any two directions; they are normalised, and must not be parallel.
    Axes {
        /// Direction of increasing `i`.
        u: [f64; 3],
        /// Direction of increasing `j`.
        v: [f64; 3],
    },
}

/// Mass of the point masses, kg.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Mass {
    /// Every vertex has this mass, kg.
    PerVertex(f64),
    /// The cloth's total mass, kg, shared equally between its `nx·ny` vertices.
    Total(f64),
}

/// A named corner of the grid. `Left` is column `i = 0`, `Right` is `i = nx-1`,
/// `Bottom` is row `j = 0`, `Top` is `j = ny-1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Corner {
    /// `(0, ny-1)`.
    TopLeft,
    /// `(nx-1, ny-1)`.
    TopRight,
    /// `(0, 0)`.
    BottomLeft,
    /// `(nx-1, 0)`.
    BottomRight,
}

/// A named edge of the grid (same convention as [`Corner`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Edge {
    /// Row `j = ny-1`.
    Top,
    /// Row `j = 0`.
    Bottom,
    /// Column `i = 0`.
    Left,
    /// Column `i = nx-1`.
    Right,
}

/// Which vertices are pinned (held fixed, infinite mass).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Pin {
    /// A named corner.
    Corner(Corner),
    /// Every vertex of a named edge.
    Edge(Edge),
    /// A vertex by its index `j·nx + i`.
    Vertex(u32),
    /// A vertex by its grid coordinates `(i, j)`.
    GridPoint(u32, u32),
}

/// Stiffness and damping of one spring kind.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    /// Hooke stiffness `k`, N/m.
    pub stiffness: f64,
    /// Damping coefficient `c_d` along the spring, N·s/m.
    pub damping: f64,
}

/// The three spring kinds of a mass-spring cloth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringSpecs {
    /// 4-neighbour springs. Default `k = 400 N/m, c_d = 0.02 N·s/m`.
    pub structural: SpringSpec,
    /// Diagonal springs. Default `k = 200 N/m, c_d = 0.01 N·s/m`.
    pub shear: SpringSpec,
    /// Springs to the vertex two steps away. Default `k = 100 N/m, c_d = 0.005 N·s/m`.
    pub bend: SpringSpec,
}

impl Default for SpringSpecs {
    fn default() -> Self {
        Self {
            structural: SpringSpec { stiffness: 400.0, damping: 0.02 },
            shear: SpringSpec { stiffness: 200.0, damping: 0.01 },
            bend: SpringSpec { stiffness: 100.0, damping: 0.005 },
        }
    }
}

/// A sphere the cloth collides with, as a scene's `spheres` list gives it (it becomes a
/// [`ColliderSpec`] with a [`crate::colliders::Shape::Sphere`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SphereSpec {
    /// Centre, m. Default `(0, 1, 0)`.
    pub center: [f64; 3],
    /// Radius, m. Default 0.5.
    pub radius: f64,
    /// Contact (penalty) stiffness `k_c`, N/m: `F_c = k_c d`. Default 1000.
    pub stiffness: f64,
    /// Friction coefficient `c_f` (dimensionless). Default 0.5.
    pub friction: f64,
    /// Damping of the normal approach velocity while in contact, N·s/m. Default 0.2.
    pub damping: f64,
    /// How the sphere moves, for the `MovingColliders` effect (from `center`). Default: no motion.
    pub motion: Motion,
}

impl Default for SphereSpec {
    fn default() -> Self {
        Self {
            center: [0.0, 1.0, 0.0],
            radius: 0.5,
            stiffness: 1000.0,
            friction: 0.5,
            damping: 0.2,
            motion: Motion::default(),
        }
    }
}

/// A prescribed motion from a start position: the displacement at time `t` (s) is
/// `d(t) = velocity · t + amplitude · sin(2π frequency t)`, m, and the velocity
/// `d'(t) = velocity + amplitude · 2π frequency · cos(2π frequency t)`, m/s.
///
/// Pins may also turn: with an angular velocity `ω` (rad/s) about an axis through `pivot`, which
/// the displacement carries along, a pin that starts at `x₀` is at
/// `x(t) = p(t) + R(ω t)(x₀ − pivot)` with `p(t) = pivot + d(t)` and `R(θ)` the rotation by `|θ|`
/// about `θ/|θ|` (right-handed), and moves at `d'(t) + ω × (x(t) − p(t))`. Colliders only
/// translate (their `angular_velocity` must be zero).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Motion {
    /// Steady velocity, m/s. Default `(0, 0, 0)`.
    pub velocity: [f64; 3],
    /// Amplitude of the oscillation, m. Default `(0, 0, 0)`.
    pub amplitude: [f64; 3],
    /// Frequency of the oscillation, Hz. Default 0.
    pub frequency: f64,
    /// Angular velocity `ω`, rad/s: the axis times the rate (pins only). Default `(0, 0, 0)`.
    pub angular_velocity: [f64; 3],
    /// The point the rotation turns about at `t = 0`, m. Default `(0, 0, 0)`.
    pub pivot: [f64; 3],
}

impl Motion {
    /// Angular frequency `2π f`, rad/s.
    pub fn angular_frequency(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.frequency
    }

    /// Largest speed of the motion's translation, m/s (`|velocity| + |amplitude| · 2π f`, a
    /// bound).
    pub fn max_speed(&self) -> f64 {
        norm(self.velocity) + norm(self.amplitude) * self.angular_frequency()
    }

    /// Largest speed of a point `radius` (m) from the pivot, m/s: the translation's bound plus
    /// `|ω| · radius`.
    pub fn max_speed_at(&self, radius: f64) -> f64 {
        self.max_speed() + norm(self.angular_velocity) * radius
    }

    /// Whether the motion turns (a non-zero angular velocity).
    pub fn turns(&self) -> bool {
        self.angular_velocity != [0.0; 3]
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The wind of the `Wind` effect: air moving at `velocity · (1 + gust_amplitude · sin(2π t /
/// gust_period))` pushes on each vertex along the cloth's normal `n`,
/// `F = coefficient · A · ((w − v) · n) n`, with `A` the cloth's area per vertex.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WindSpec {
    /// Mean wind velocity, m/s. Default `(0, 0, 0)`.
    pub velocity: [f64; 3],
    /// Relative amplitude of the gusts (0: steady wind). Default 0.
    pub gust_amplitude: f64,
    /// Period of the gusts, s. Default 2.
    pub gust_period: f64,
    /// Pressure per unit normal speed and area, N·s/m³ (about ½ ρ C_d |w| for air, ρ = 1.2 kg/m³).
    /// Default 1.
    pub coefficient: f64,
}

impl Default for WindSpec {
    fn default() -> Self {
        Self { velocity: [0.0; 3], gust_amplitude: 0.0, gust_period: 2.0, coefficient: 1.0 }
    }
}

/// Time stepping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TimeSpec {
    /// Length of one displayed frame, s. Default 1/60.
    pub frame_dt: f64,
    /// Substeps per frame; each substep advances `frame_dt / substeps`. Default `Fixed(40)`.
    pub substeps: Substeps,
    /// How many frames `cloth run` simulates when not told. Default 300 (5 s).
    pub frames: u32,
}

impl Default for TimeSpec {
    fn default() -> Self {
        Self { frame_dt: 1.0 / 60.0, substeps: Substeps::Fixed(40), frames: 300 }
    }
}

/// Substeps per frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Substeps {
    /// Exactly this many substeps per frame.
    Fixed(u32),
    /// The fewest substeps that keep each one below [`Auto::SAFETY`] of the stable bound (for
    /// XPBD, which has none, below `XPBD_AUTO_OMEGA_DT / ω_max`: see
    /// [`crate::stability::auto_target_substep`]).
    Auto,
}

/// Constants of [`Substeps::Auto`].
pub struct Auto;
impl Auto {
    /// Fraction of the largest stable substep that `Auto` aims for.
    pub const SAFETY: f64 = 0.8;
}

impl Scene {
    /// Serialises the scene as pretty RON.
    pub fn to_ron_string(&self) -> String {
        let config = ron::ser::PrettyConfig::new().depth_limit(4).struct_names(true);
        ron::ser::to_string_pretty(self, config).unwrap_or_else(|e| format!("// cannot serialise: {e}"))
    }

    /// Number of vertices `nx · ny`.
    pub fn vertex_count(&self) -> usize {
        self.cloth.resolution[0] as usize * self.cloth.resolution[1] as usize
    }

    /// Mass of each vertex, kg.
    pub fn vertex_mass(&self) -> f64 {
        match self.cloth.mass {
            Mass::PerVertex(m) => m,
            Mass::Total(total) => total / self.vertex_count().max(1) as f64,
        }
    }
}
