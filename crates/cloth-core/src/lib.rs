//! # cloth-core
//!
//! The backend-agnostic heart of the cloth workbench, written to be read:
//!
//! * [`scene`]: what to simulate, loaded from RON ([`Scene`]), and [`validation`], with the
//!   limits of [`budget`];
//! * [`effects`]: the physical effects a scene switches on ([`EffectSet`]);
//! * [`colliders`]: spheres, ground planes, capsules, boxes and meshes, and their signed distances;
//! * [`mesh`]: OBJ meshes read, checked closed and sampled as signed distance fields;
//! * [`grid`] and [`springs`]: the `nx × ny` mesh and its structural, shear and bend springs;
//! * [`model`]: grid + springs + per-vertex spring lists, the one source every backend uses;
//! * [`coloring`]: the springs in sets that share no vertex (XPBD's parallel projection order),
//!   and the vertices in sets that share no spring;
//! * [`quantities`]: what a substep derives from a scene (masses, rest lengths, wind), once;
//! * [`forces`]: the force model, one function per force, and the springs' Jacobian blocks;
//! * [`implicit`]: the linear system of a backward-Euler substep and its conjugate gradients;
//! * [`vbd`]: Vertex Block Descent's per-vertex Newton step and its sweep over the vertex colours;
//! * [`self_collision`]: vertices closer than the thickness repel, found by a spatial hash;
//! * [`motion`]: moving pins and colliders, and the gusting wind;
//! * [`constraints`]: XPBD's constraint projections, one function per constraint;
//! * [`reference`](mod@reference): the CPU reference stepper, the test oracle;
//! * [`integrator`]: semi-implicit Euler (the model's), velocity Verlet, RK4;
//! * [`stability`]: the largest stable substep;
//! * [`simulator`]: the [`Simulator`] trait every backend implements;
//! * [`energy`]: kinetic, elastic, gravitational and contact energy;
//! * [`intersections`]: where the cloth passes through itself, counted exactly;
//! * [`export`]: the cloth as a Wavefront OBJ;
//! * [`output`]: files written whole or not at all (a temporary file renamed into place);
//! * [`tessellation`]: the colliders as triangle meshes, and the cloth's vertex normals.
//!
//! ```
//! use cloth_core::{Scene, Simulator, CpuSimulator};
//! let mut scene = Scene::default();
//! scene.cloth.resolution = [8, 8];
//! let mut sim = CpuSimulator::new(&scene).unwrap();
//! sim.advance(10).unwrap();
//! let state = sim.read_state().unwrap();
//! assert_eq!(state.non_finite_count(), 0);
//! assert!(state.centroid()[1] < 1.8, "the cloth falls");
//! ```

#![warn(missing_docs)]

pub mod budget;
pub mod colliders;
pub mod coloring;
pub mod constraints;
pub mod effects;
pub mod energy;
pub mod error;
pub mod export;
pub mod forces;
pub mod grid;
pub mod implicit;
pub mod integrator;
pub mod intersections;
pub mod mesh;
pub mod model;
pub mod motion;
pub mod multigrid;
pub mod output;
pub mod quantities;
pub mod real;
pub mod reference;
pub mod scene;
pub mod self_collision;
pub mod simulator;
pub mod solver;
pub mod springs;
pub mod stability;
pub mod tessellation;
pub mod validation;
pub mod vbd;

pub use effects::{Effect, EffectSet};
pub use energy::Energy;
pub use error::{Problem, SceneError, SimError};
pub use integrator::Integrator;
pub use model::ClothModel;
pub use quantities::SceneQuantities;
pub use reference::{CpuSimulator, CpuSimulatorF64, ReferenceSimulator};
pub use scene::{Scene, Substeps};
pub use simulator::{AdvanceCounts, ClothState, Diagnostics, PassTime, Simulator};
pub use springs::SpringKind;
