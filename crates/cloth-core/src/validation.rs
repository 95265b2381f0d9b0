//! Scene validation: every problem at once, each naming the field and the fix.

use crate::budget::{F32_MEANINGFUL, MAX_FRAMES, MAX_SUBSTEPS_PER_FRAME};
use crate::colliders::{ColliderSpec, Shape};
use crate::effects::Effect;
use crate::error::{Problem, SceneError};
use crate::grid::pin_indices;
use crate::model::ClothModel;
use crate::scene::{Mass, Orientation, Scene, SpringSpec, Substeps};
use crate::stability;

/// Largest host memory a scene may need, bytes (8 GiB): beyond it the grid is refused
/// before anything is allocated.
pub const MAX_HOST_BYTES: u64 = 8 << 30;

/// Largest scene file read, bytes (1 MiB; the scenes of `scenes/` are a few KiB): a larger file,
/// or one that is not a regular file (a device, a pipe), is refused before it is read.
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// Most problems one validation lists; the rest are counted in one last entry.
pub const MAX_PROBLEMS: usize = 20;

struct Checker {
    problems: Vec<Problem>,
    /// Problems found beyond [`MAX_PROBLEMS`].
    more: usize,
}

impl Checker {
    fn fail(&mut self, field: impl Into<String>, message: impl Into<String>, fix: impl Into<String>) {
        if self.problems.len() < MAX_PROBLEMS {
            self.problems.push(Problem { field: field.into(), message: message.into(), fix: fix.into() });
        } else {
            self.more += 1;
        }
    }

    /// Whether `v` is finite and, unless 0, within [`F32_MEANINGFUL`] in magnitude.
    fn finite(&mut self, field: &str, v: f64) -> bool {
        let [lo, hi] = F32_MEANINGFUL;
        if !v.is_finite() {
            self.fail(field, format!("is {v}, not a finite number"), "write a finite number");
            false
        } else if v != 0.0 && !(lo..=hi).contains(&v.abs()) {
            self.fail(
                field,
                format!("is {v:e}, outside the {lo:e} to {hi:e} in magnitude that f32 arithmetic keeps meaningful"),
                format!("give 0 or a value between {lo:e} and {hi:e} in magnitude, in SI units"),
            );
            false
        } else {
            true
        }
    }

    fn positive(&mut self, field: &str, v: f64, unit: &str) {
        if self.finite(field, v) && v <= 0.0 {
            self.fail(
                field,
                format!("is {v} {unit}, must be greater than 0"),
                format!("give a positive value in {unit}"),
            );
        }
    }

    fn non_negative(&mut self, field: &str, v: f64, unit: &str) {
        if self.finite(field, v) && v < 0.0 {
            self.fail(
                field,
                format!("is {v} {unit}, must not be negative"),
                format!("give 0 or a positive value in {unit}"),
            );
        }
    }

    fn vector(&mut self, field: &str, v: [f64; 3]) -> bool {
        let mut ok = true;
        for (i, x) in v.iter().enumerate() {
            ok &= self.finite(&format!("{field}[{i}]"), *x);
        }
        ok
    }

    /// A collider: its shape's sizes, its contact parameters and its motion.
    fn collider(&mut self, field: &str, collider: &ColliderSpec) {
        let f = |name: &str| format!("{field}.{name}");
        match &collider.shape {
            Shape::Sphere { center, radius } => {
                self.vector(&f("shape.Sphere.center"), *center);
                self.positive(&f("shape.Sphere.radius"), *radius, "m");
            }
            Shape::Plane { normal, offset } => {
                if self.vector(&f("shape.Plane.normal"), *normal) && normal.iter().all(|x| *x == 0.0) {
                    self.fail(
                        f("shape.Plane.normal"),
                        "is (0, 0, 0): a plane needs a direction",
                        "give the outward direction, e.g. (0, 1, 0) for a ground",
                    );
                }
                self.finite(&f("shape.Plane.offset"), *offset);
            }
            Shape::Capsule { a, b, radius } => {
                let ends = self.vector(&f("shape.Capsule.a"), *a) & self.vector(&f("shape.Capsule.b"), *b);
                self.positive(&f("shape.Capsule.radius"), *radius, "m");
                if ends && a == b {
                    self.fail(
                        f("shape.Capsule.b"),
                        format!("equals a, {a:?}: the capsule has no axis"),
                        "give two distinct ends (a sphere is Sphere(center, radius))",
                    );
                }
            }
            Shape::Mesh { center, scale, axis, angle, cells, .. } => {
                self.vector(&f("shape.Mesh.center"), *center);
                let before = self.problems.len() + self.more;
                self.positive(&f("shape.Mesh.scale"), *scale, "(m per file unit)");
                if self.vector(&f("shape.Mesh.axis"), *axis) && axis.iter().all(|x| *x == 0.0) {
                    self.fail(
                        f("shape.Mesh.axis"),
                        "is (0, 0, 0): a rotation needs an axis",
                        "give a direction, e.g. (0, 1, 0) (with angle 0 for no rotation)",
                    );
                }
                self.finite(&f("shape.Mesh.angle"), *angle);
                if !(2..=crate::mesh::MAX_CELLS).contains(cells) {
                    self.fail(
                        f("shape.Mesh.cells"),
                        format!(
                            "is {cells}: the distance field needs 2 to {} cells along the mesh",
                            crate::mesh::MAX_CELLS
                        ),
                        "give a number of cells in that range (32 is the default)",
                    );
                }
                // Read and sample the mesh only once its parameters are sound.
                if self.problems.len() + self.more == before
                    && let Some(Err(e)) = collider.shape.distance_field()
                {
                    let fix = match e {
                        crate::mesh::MeshError::Unreadable { .. } => {
                            "give the path of a readable OBJ file, relative to the scene file's folder"
                        }
                        crate::mesh::MeshError::Parse { .. } => "fix that line of the OBJ file",
                        crate::mesh::MeshError::NotClosed { .. } => "close the mesh's holes (every edge in two faces)",
                        crate::mesh::MeshError::Empty { .. } => "give an OBJ file with faces",
                        crate::mesh::MeshError::TooLarge { .. } => "lower `cells` or simplify the mesh",
                    };
                    self.fail(f("shape.Mesh.file"), e.to_string(), fix);
                }
            }
            Shape::Box { center, half_extents, axis, angle, rounding } => {
                self.vector(&f("shape.Box.center"), *center);
                let mut sides = true;
                for (i, h) in half_extents.iter().enumerate() {
                    let before = self.problems.len() + self.more;
                    self.positive(&f(&format!("shape.Box.half_extents[{i}]")), *h, "m");
                    sides &= self.problems.len() + self.more == before;
                }
                if self.vector(&f("shape.Box.axis"), *axis) && axis.iter().all(|x| *x == 0.0) {
                    self.fail(
                        f("shape.Box.axis"),
                        "is (0, 0, 0): a rotation needs an axis",
                        "give a direction, e.g. (0, 1, 0) (with angle 0 for no rotation)",
                    );
                }
                self.finite(&f("shape.Box.angle"), *angle);
                self.non_negative(&f("shape.Box.rounding"), *rounding, "m");
                let smallest = half_extents.iter().copied().fold(f64::INFINITY, f64::min);
                if sides && rounding.is_finite() && *rounding > smallest {
                    self.fail(
                        f("shape.Box.rounding"),
                        format!("is {rounding} m, more than the smallest half extent, {smallest} m"),
                        format!("give a rounding between 0 and {smallest} m"),
                    );
                }
            }
        }
        self.non_negative(&f("stiffness"), collider.stiffness, "N/m");
        self.non_negative(&f("friction"), collider.friction, "(dimensionless)");
        self.non_negative(&f("damping"), collider.damping, "N·s/m");
        self.motion(&f("motion"), &collider.motion);
        if collider.motion.turns() {
            self.fail(
                f("motion.angular_velocity"),
                format!("is {:?} rad/s, but colliders only translate", collider.motion.angular_velocity),
                "give (0, 0, 0); turning motions are for pins",
            );
        }
    }

    fn motion(&mut self, field: &str, m: &crate::scene::Motion) {
        self.vector(&format!("{field}.velocity"), m.velocity);
        self.vector(&format!("{field}.amplitude"), m.amplitude);
        self.non_negative(&format!("{field}.frequency"), m.frequency, "Hz");
        self.vector(&format!("{field}.angular_velocity"), m.angular_velocity);
        self.vector(&format!("{field}.pivot"), m.pivot);
    }

    /// The `self_collision` field, and what the speed limit needs of the substep: a vertex at the
    /// limit moves at most half the thickness a substep, and moving pins (which the limit does
    /// not hold back) go no faster than it.
    fn self_collision(&mut self, scene: &Scene) {
        let s = &scene.self_collision;
        let before = self.problems.len() + self.more;
        match s.thickness {
            crate::self_collision::Thickness::Spacings(f) => {
                self.positive("self_collision.thickness.Spacings", f, "(grid spacings)")
            }
            crate::self_collision::Thickness::Meters(m) => self.positive("self_collision.thickness.Meters", m, "m"),
        }
        self.non_negative("self_collision.stiffness", s.stiffness, "N/m");
        self.non_negative("self_collision.damping", s.damping, "N·s/m");
        self.non_negative("self_collision.friction", s.friction, "(dimensionless)");
        self.positive("self_collision.max_speed", s.max_speed, "m/s");
        match s.margin {
            crate::self_collision::Thickness::Spacings(f) => {
                self.positive("self_collision.margin.Spacings", f, "(grid spacings)")
            }
            crate::self_collision::Thickness::Meters(m) => self.positive("self_collision.margin.Meters", m, "m"),
        }
        if self.problems.len() + self.more != before || self.problems.iter().any(|p| p.field.starts_with("time")) {
            return;
        }
        let q = crate::self_collision::SelfCollisionQuantities::of(scene);
        let dt = scene.substep_dt();
        if dt.is_finite() && 2.0 * q.max_speed * dt > q.thickness {
            self.fail(
                "self_collision.max_speed",
                format!(
                    "is {} m/s: at the limit a vertex moves {:.3e} m a substep, more than half the thickness, {:.3e} m, so it could pass through another layer",
                    q.max_speed,
                    q.max_speed * dt,
                    q.thickness / 2.0
                ),
                format!(
                    "lower self_collision.max_speed to at most {:.3e} m/s, thicken the cloth, or take more substeps",
                    q.thickness / (2.0 * dt)
                ),
            );
        }
        if !scene.effects.contains(Effect::MovingPins) {
            return;
        }
        // A turning group's pins are as fast as the one farthest from its pivot.
        let grid = crate::grid::Grid::new(&scene.cloth);
        for group in 0..=scene.cloth.pin_groups.len() {
            let Some(motion) = scene.pin_group_motion(group) else { continue };
            let radius = (0..grid.vertex_count())
                .filter(|&i| grid.pinned[i] && grid.pin_group[i] as usize == group)
                .map(|i| {
                    let d = [0, 1, 2].map(|k| grid.positions[i][k] - motion.pivot[k]);
                    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
                })
                .fold(0.0, f64::max);
            let speed = if motion.turns() { motion.max_speed_at(radius) } else { motion.max_speed() };
            if speed > q.max_speed {
                let field = if group == 0 {
                    "cloth.pin_motion".to_string()
                } else {
                    format!("cloth.pin_groups[{}].motion", group - 1)
                };
                self.fail(
                    field,
                    format!(
                        "moves its pins at up to {speed:.3} m/s, faster than self_collision.max_speed, {} m/s \
                         (the candidate lists' checks assume no vertex is faster)",
                        q.max_speed
                    ),
                    "slow the pins' motion or raise self_collision.max_speed",
                );
            }
        }
    }

    /// The `solver` field, for the integrator that reads it.
    fn solver(&mut self, s: &crate::solver::SolverSpec, integrator: crate::Integrator) {
        use crate::solver::{MAX_NEWTON_ITERATIONS, MAX_SOLVER_ITERATIONS};
        let mut count = |field: &str, n: u32, max: u32| {
            if n == 0 || n > max {
                self.fail(
                    format!("solver.{field}"),
                    format!("is {n}; {} needs 1 to {max}", integrator.name()),
                    format!("give a count from 1 to {max}"),
                );
            }
        };
        if integrator == crate::Integrator::BackwardEuler {
            count("newton_iterations", s.newton_iterations, MAX_NEWTON_ITERATIONS);
            count("cg_max_iterations", s.cg_max_iterations, MAX_SOLVER_ITERATIONS);
            if self.finite("solver.cg_tolerance", s.cg_tolerance) && !(0.0..1.0).contains(&s.cg_tolerance) {
                self.fail(
                    "solver.cg_tolerance",
                    format!("is {}, a relative residual must be in [0, 1)", s.cg_tolerance),
                    "give e.g. 1e-4, or 0 to run cg_max_iterations every solve",
                );
            }
        } else {
            count("vbd_iterations", s.vbd_iterations, MAX_SOLVER_ITERATIONS);
            if self.finite("solver.chebyshev_rho", s.chebyshev_rho) && !(0.0..1.0).contains(&s.chebyshev_rho) {
                self.fail(
                    "solver.chebyshev_rho",
                    format!("is {}, a convergence rate must be in [0, 1)", s.chebyshev_rho),
                    "give the sweeps' measured rate (e.g. 0.65), or 0 to turn Chebyshev acceleration off",
                );
            }
        }
    }

    fn spring(&mut self, field: &str, s: &SpringSpec) {
        self.non_negative(&format!("{field}.stiffness"), s.stiffness, "N/m");
        self.non_negative(&format!("{field}.damping"), s.damping, "N·s/m");
    }
}

impl Scene {
    /// Checks every field. Returns the warnings (problems that still let the scene run, such as
    /// a substep above the stability bound), or [`SceneError::Invalid`] listing every error.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] when any value is unusable.
    pub fn validate(&self) -> Result<Vec<Problem>, SceneError> {
        let mut c = Checker { problems: Vec::new(), more: 0 };
        let cloth = &self.cloth;
        let [nx, ny] = cloth.resolution;
        let mut grid_ok = true;
        for (k, n) in [nx, ny].into_iter().enumerate() {
            if n < 2 {
                grid_ok = false;
                c.fail(
                    format!("cloth.resolution[{k}]"),
                    format!("is {n} vertices; a cloth needs at least 2 along each side"),
                    "use 2 or more (e.g. (32, 32))",
                );
            }
        }
        if grid_ok {
            let host_bytes = ClothModel::estimated_host_bytes(self);
            if (nx as u64) * (ny as u64) > u32::MAX as u64 / 2 || host_bytes > MAX_HOST_BYTES {
                // Nothing sized by the grid (a pinned edge's vertex list) is built for it.
                grid_ok = false;
                c.fail(
                    "cloth.resolution",
                    format!(
                        "grid {nx}x{ny} needs about {} MiB of memory, more than the {} MiB this tool allocates",
                        host_bytes >> 20,
                        MAX_HOST_BYTES >> 20
                    ),
                    "use a smaller grid",
                );
            }
        }
        for (k, s) in cloth.size.iter().enumerate() {
            c.positive(&format!("cloth.size[{k}]"), *s, "m");
        }
        c.vector("cloth.center", cloth.center);
        c.vector("cloth.initial_velocity", cloth.initial_velocity);
        if let Orientation::Axes { u, v } = &cloth.orientation {
            let ok = c.vector("cloth.orientation.u", *u) & c.vector("cloth.orientation.v", *v);
            let cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            if ok && norm(cross) <= 1e-9 * norm(*u) * norm(*v) {
                c.fail("cloth.orientation", "u and v are zero or parallel", "give two non-parallel directions");
            }
        }
        match cloth.mass {
            Mass::PerVertex(m) => c.positive("cloth.mass.PerVertex", m, "kg"),
            Mass::Total(m) => c.positive("cloth.mass.Total", m, "kg"),
        }
        let m = self.vertex_mass();
        if c.problems.is_empty() && grid_ok && !(F32_MEANINGFUL[0]..=F32_MEANINGFUL[1]).contains(&m) {
            c.fail(
                "cloth.mass",
                format!("gives {m:e} kg a vertex, outside what f32 arithmetic keeps meaningful"),
                format!("give a mass of {:e} to {:e} kg a vertex", F32_MEANINGFUL[0], F32_MEANINGFUL[1]),
            );
        }
        let vertex_count = nx as u64 * ny as u64;
        let groups = std::iter::once(("cloth.pins".to_string(), &cloth.pins))
            .chain(cloth.pin_groups.iter().enumerate().map(|(k, g)| (format!("cloth.pin_groups[{k}].pins"), &g.pins)));
        let pins = groups
            .flat_map(|(field, pins)| pins.iter().enumerate().map(move |(k, pin)| (format!("{field}[{k}]"), pin)));
        for (field, pin) in pins.filter(|_| grid_ok) {
            if let Some(bad) = pin_indices(pin, nx, ny).into_iter().find(|&i| i >= vertex_count) {
                let shown =
                    if bad == u64::MAX { "a point outside the grid".to_string() } else { format!("vertex {bad}") };
                c.fail(
                    field,
                    format!("{pin:?} names {shown}, but the grid has {vertex_count} vertices ({nx}x{ny})"),
                    format!("use an index below {vertex_count}, or i < {nx} and j < {ny}"),
                );
            }
        }
        c.spring("springs.structural", &self.springs.structural);
        c.spring("springs.shear", &self.springs.shear);
        c.spring("springs.bend", &self.springs.bend);
        if self.colliders.len() > crate::colliders::MAX_COLLIDERS {
            c.fail(
                "colliders",
                format!(
                    "lists {} colliders, more than the {} a scene may have",
                    self.colliders.len(),
                    crate::colliders::MAX_COLLIDERS
                ),
                "merge colliders into fewer (several boxes into one mesh, say) or remove some",
            );
        }
        for (k, collider) in self.colliders.iter().enumerate() {
            c.collider(&format!("colliders[{k}]"), collider);
        }
        c.motion("cloth.pin_motion", &cloth.pin_motion);
        if cloth.pin_groups.len() >= crate::scene::MAX_PIN_GROUPS {
            c.fail(
                "cloth.pin_groups",
                format!(
                    "lists {} groups; with cloth.pins a cloth may have {} pin groups",
                    cloth.pin_groups.len(),
                    crate::scene::MAX_PIN_GROUPS
                ),
                format!("merge groups that move alike, down to {}", crate::scene::MAX_PIN_GROUPS - 1),
            );
        }
        for (k, group) in cloth.pin_groups.iter().enumerate() {
            c.motion(&format!("cloth.pin_groups[{k}].motion"), &group.motion);
        }
        if c.finite("cloth.ripple.amplitude", cloth.ripple.amplitude) && cloth.ripple.amplitude != 0.0 {
            c.positive("cloth.ripple.wavelength", cloth.ripple.wavelength, "m");
        }
        c.vector("wind.velocity", self.wind.velocity);
        c.non_negative("wind.gust_amplitude", self.wind.gust_amplitude, "(relative)");
        c.positive("wind.gust_period", self.wind.gust_period, "s");
        c.non_negative("wind.coefficient", self.wind.coefficient, "N·s/m³");
        c.vector("gravity", self.gravity);
        c.non_negative("air_drag", self.air_drag, "1/s");
        c.positive("time.frame_dt", self.time.frame_dt, "s");
        match self.time.substeps {
            Substeps::Fixed(0) => c.fail(
                "time.substeps",
                "is Fixed(0); a frame needs at least one substep",
                "use Fixed(1) or more, or Auto",
            ),
            Substeps::Fixed(n) if n > MAX_SUBSTEPS_PER_FRAME => c.fail(
                "time.substeps",
                format!("is Fixed({n}), more than the {MAX_SUBSTEPS_PER_FRAME} substeps one frame may take"),
                format!("use at most Fixed({MAX_SUBSTEPS_PER_FRAME}), or shorten time.frame_dt"),
            ),
            _ => {}
        }
        if self.time.frames > MAX_FRAMES {
            c.fail(
                "time.frames",
                format!("is {}, more than the {MAX_FRAMES} frames one command may run", self.time.frames),
                format!("use at most {MAX_FRAMES}"),
            );
        }
        if self.effects.contains(Effect::Friction) && !self.effects.contains(Effect::Contact) {
            c.fail(
                "effects",
                "Friction is listed without Contact; friction acts only in contact",
                "add Contact or remove Friction",
            );
        }
        if self.effects.contains(Effect::SelfCollision) {
            c.self_collision(self);
        }
        if self.integrator.is_implicit() {
            c.solver(&self.solver, self.integrator);
        }
        if c.more > 0 {
            let message = format!("{} more problem(s) not listed", c.more);
            c.problems.push(Problem { field: "…".into(), message, fix: "fix the ones above and check again".into() });
        }
        if !c.problems.is_empty() {
            return Err(SceneError::Invalid(c.problems));
        }

        // The work the substeps ask for, once the values they come from are known to be sound.
        let too_stiff = "lower the stiffness or the contact stiffness, raise the mass, or shorten time.frame_dt";
        let bound = stability::stable_substep(self);
        if bound.is_nan() || bound <= 0.0 {
            let message = format!("the largest stable substep comes out as {bound}: the scene's values do not combine");
            return Err(SceneError::Invalid(vec![Problem { field: "time".into(), message, fix: too_stiff.into() }]));
        }
        let auto = stability::auto_substeps_needed(self);
        if self.time.substeps == Substeps::Auto && auto > MAX_SUBSTEPS_PER_FRAME as f64 {
            let message = format!(
                "is Auto, which needs {auto:.3e} substeps a frame, more than the {MAX_SUBSTEPS_PER_FRAME} one frame may take"
            );
            return Err(SceneError::Invalid(vec![Problem {
                field: "time.substeps".into(),
                message,
                fix: too_stiff.into(),
            }]));
        }
        let mut warnings = Vec::new();
        let dt = self.substep_dt();
        if dt > bound {
            let needed = (self.time.frame_dt / bound).ceil();
            let fix = if needed <= MAX_SUBSTEPS_PER_FRAME as f64 {
                format!("use Fixed({needed}) or more substeps per frame, or Auto")
            } else {
                format!("no substep count up to the {MAX_SUBSTEPS_PER_FRAME} allowed is stable: {too_stiff}")
            };
            warnings.push(Problem {
                field: "time.substeps".into(),
                message: format!(
                    "substep {dt:.3e} s is {:.2}x the largest stable substep {bound:.3e} s: the simulation will blow up",
                    dt / bound
                ),
                fix,
            });
        }
        Ok(warnings)
    }
}

impl Scene {
    /// Parses a RON scene and validates it.
    ///
    /// # Errors
    /// [`SceneError::Parse`] with line and column for malformed text,
    /// [`SceneError::Invalid`] listing every validation problem.
    pub fn from_ron_str(text: &str) -> Result<Self, SceneError> {
        // A byte-order mark (some editors write one) is not part of the scene.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let scene: Scene = ron::de::from_str(text).map_err(SceneError::from_ron)?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads, parses and validates a RON scene file.
    ///
    /// # Errors
    /// [`SceneError::Io`] when the file cannot be read, is not a regular file, or is larger than
    /// [`MAX_SCENE_BYTES`]; else as [`Scene::from_ron_str`].
    pub fn load(path: &std::path::Path) -> Result<Self, SceneError> {
        use std::io::Read as _;
        let io = |error| SceneError::Io { path: path.display().to_string(), error };
        let invalid = |what: String| io(std::io::Error::new(std::io::ErrorKind::InvalidInput, what));
        let file = std::fs::File::open(path).map_err(io)?;
        if !file.metadata().map_err(io)?.is_file() {
            return Err(invalid("it is not a regular file".into()));
        }
        let mut text = String::new();
        file.take(MAX_SCENE_BYTES + 1).read_to_string(&mut text).map_err(io)?;
        if text.len() as u64 > MAX_SCENE_BYTES {
            return Err(invalid(format!("it is larger than {MAX_SCENE_BYTES} bytes, the most a scene file may be")));
        }
        let scene: Scene =
            ron::de::from_str(text.strip_prefix('\u{feff}').unwrap_or(&text)).map_err(SceneError::from_ron)?;
        let scene = scene.with_paths_from(path.parent().unwrap_or(std::path::Path::new("")));
        scene.validate()?;
        Ok(scene)
    }

    /// The scene with every relative mesh file joined to `folder` (the folder of the scene file
    /// it was read from: a scene names its meshes relative to itself).
    pub fn with_paths_from(mut self, folder: &std::path::Path) -> Self {
        for collider in &mut self.colliders {
            if let Shape::Mesh { file, .. } = &mut collider.shape
                && std::path::Path::new(file.as_str()).is_relative()
            {
                *file = folder.join(file.as_str()).display().to_string();
            }
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Corner, Pin, SphereSpec};

    fn fields(scene: &Scene) -> Vec<String> {
        match scene.validate() {
            Err(SceneError::Invalid(p)) => p.into_iter().map(|p| p.field).collect(),
            other => panic!("expected invalid, got {other:?}"),
        }
    }

    #[test]
    fn default_scene_is_valid_and_stable() {
        assert_eq!(Scene::default().validate().unwrap(), vec![]);
    }

    #[test]
    fn every_problem_is_reported_at_once() {
        let mut s = Scene::default();
        s.cloth.resolution = [1, 0];
        s.cloth.mass = Mass::PerVertex(-1.0);
        s.colliders = vec![SphereSpec { radius: 0.0, friction: -0.1, ..Default::default() }.into()];
        s.springs.shear.stiffness = -5.0;
        s.time.frame_dt = f64::NAN;
        s.time.substeps = Substeps::Fixed(0);
        s.gravity[1] = f64::INFINITY;
        let f = fields(&s);
        for expected in [
            "cloth.resolution[0]",
            "cloth.resolution[1]",
            "cloth.mass.PerVertex",
            "colliders[0].shape.Sphere.radius",
            "colliders[0].friction",
            "springs.shear.stiffness",
            "time.frame_dt",
            "time.substeps",
            "gravity[1]",
        ] {
            assert!(f.iter().any(|x| x == expected), "missing {expected} in {f:?}");
        }
    }

    #[test]
    fn more_colliders_than_the_kernels_hold_are_refused() {
        let mut s = Scene {
            colliders: vec![SphereSpec::default().into(); crate::colliders::MAX_COLLIDERS],
            ..Default::default()
        };
        assert!(s.validate().is_ok(), "{} colliders are allowed", crate::colliders::MAX_COLLIDERS);
        s.colliders.push(SphereSpec::default().into());
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("colliders: lists 65 colliders, more than the 64 a scene may have"), "{err}");
    }

    #[test]
    fn messages_name_the_value_and_the_fix() {
        let mut s = Scene::default();
        s.cloth.mass = Mass::Total(0.0);
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("cloth.mass.Total: is 0 kg, must be greater than 0"), "{err}");
        assert!(err.contains("fix: give a positive value in kg"), "{err}");
    }

    #[test]
    fn out_of_range_pins_are_reported() {
        let mut s = Scene::default();
        s.cloth.resolution = [4, 4];
        s.cloth.pins = vec![Pin::Corner(Corner::TopLeft), Pin::Vertex(16), Pin::GridPoint(4, 0)];
        let err = s.validate().unwrap_err();
        let f: Vec<_> = err.problems().iter().map(|p| p.field.as_str()).collect();
        assert_eq!(f, ["cloth.pins[1]", "cloth.pins[2]"]);
        assert!(err.to_string().contains("Vertex(16) names vertex 16, but the grid has 16 vertices (4x4)"), "{err}");
    }

    #[test]
    fn pin_groups_are_checked_like_pins_and_colliders_do_not_turn() {
        use crate::scene::{Motion, PinGroup};
        let mut s = Scene::default();
        s.cloth.resolution = [4, 4];
        let turning = Motion { angular_velocity: [0.0, 1.0, 0.0], ..Default::default() };
        s.cloth.pin_groups = vec![PinGroup { pins: vec![Pin::Vertex(3), Pin::Vertex(20)], motion: turning }];
        s.colliders[0].motion = turning;
        let err = s.validate().unwrap_err();
        let f: Vec<_> = err.problems().iter().map(|p| p.field.as_str()).collect();
        assert_eq!(f, ["cloth.pin_groups[0].pins[1]", "colliders[0].motion.angular_velocity"], "{err}");
        assert!(err.to_string().contains("colliders only translate"), "{err}");
        // Four groups at most, cloth.pins among them.
        s.colliders[0].motion = Motion::default();
        s.cloth.pin_groups = vec![PinGroup::default(); crate::scene::MAX_PIN_GROUPS - 1];
        assert!(s.validate().is_ok());
        s.cloth.pin_groups.push(PinGroup::default());
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("cloth.pin_groups: lists 4 groups; with cloth.pins a cloth may have 4"), "{err}");
    }

    #[test]
    fn a_turning_pin_group_is_as_fast_as_its_farthest_pin() {
        // The default cloth is 2 m wide: an edge turning about its middle at 5 rad/s moves its
        // end pins at 5 m/s, within a 6 m/s speed limit; at 7 rad/s they are too fast.
        let mut s = Scene::default();
        s.effects = s.effects.with(Effect::MovingPins).with(Effect::SelfCollision);
        s.cloth.pin_groups = vec![crate::scene::PinGroup {
            pins: vec![Pin::Edge(crate::scene::Edge::Top)],
            motion: crate::scene::Motion {
                angular_velocity: [0.0, 5.0, 0.0],
                pivot: [0.0, 1.8, -1.0],
                ..Default::default()
            },
        }];
        s.validate().unwrap();
        s.cloth.pin_groups[0].motion.angular_velocity = [0.0, 7.0, 0.0];
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("cloth.pin_groups[0].motion: moves its pins at up to 7.000 m/s"), "{err}");
    }

    #[test]
    fn a_grid_too_large_is_refused_before_allocation() {
        let mut s = Scene::default();
        s.cloth.resolution = [100_000, 100_000];
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("cloth.resolution: grid 100000x100000 needs about"), "{err}");
        assert!(err.contains("use a smaller grid"), "{err}");
    }

    #[test]
    fn a_pinned_edge_of_a_grid_too_large_is_not_listed() {
        // Found by the command line's property test: `cloth bench --effects --grids 4294967295`
        // listed the flag's pinned edge, 4e9 vertices, 32 GB, before refusing the grid.
        let mut s = Scene::default();
        s.cloth.resolution = [4_000_000_000, 3];
        s.cloth.pins = vec![Pin::Edge(crate::scene::Edge::Bottom)];
        let err = s.validate().unwrap_err();
        let fields: Vec<_> = err.problems().iter().map(|p| p.field.as_str()).collect();
        assert_eq!(fields, ["cloth.resolution"], "{err}");
    }

    #[test]
    fn friction_needs_contact() {
        let mut s = Scene::default();
        s.effects = s.effects.without(Effect::Contact);
        assert_eq!(fields(&s), ["effects"]);
    }

    #[test]
    fn an_unstable_substep_is_a_warning_naming_the_fix() {
        let mut s = Scene::default();
        s.time.substeps = Substeps::Fixed(2);
        let warnings = s.validate().unwrap();
        assert_eq!(warnings.len(), 1);
        assert_eq!(warnings[0].field, "time.substeps");
        assert!(warnings[0].message.contains("largest stable substep"));
        assert!(warnings[0].fix.starts_with("use Fixed("));
    }
}
