//! # cloth-export
//!
//! A run of the cloth workbench as files other tools open:
//!
//! * [`glb`]: one binary glTF 2.0 file (`.glb`): the cloth's triangle mesh with normals and
//!   texture coordinates, each collider as a mesh of its own, and the motion as an animation of
//!   morph targets (one a kept frame) on the simulated clock; Blender, three.js and every glTF
//!   viewer import it;
//! * [`folder`]: a folder of Wavefront OBJ files, one a kept frame (the cloth), one for the
//!   colliders, and a CSV of the per-frame diagnostics for a notebook;
//! * [`read`]: a GLB read back (the scene it embeds and the positions of every kept frame).
//!
//! An export is planned before the run ([`ExportPlan::new`]: the target, the frames it keeps, a
//! run too large for the format refused with the number of frames that fit), then fed the kept
//! states as the run produces them ([`Exporter::record`]) and finished ([`Exporter::finish`]).
//! Every file is written whole or not at all: to a temporary file beside it, renamed into place
//! when complete; an export dropped before it is finished (an error, a cancelled run) removes
//! its temporary files.
//!
//! ```
//! use cloth_core::{CpuSimulator, Scene, Simulator};
//! use cloth_export::{ExportPlan, Exporter};
//! let mut scene = Scene::default();
//! scene.cloth.resolution = [8, 8];
//! let path = std::env::temp_dir().join(format!("doc-{}.glb", std::process::id()));
//! let plan = ExportPlan::new(&path, &scene, 4, 2).unwrap();
//! let mut sim = CpuSimulator::new(&scene).unwrap();
//! let mut export = Exporter::start(&plan, &scene, &sim.read_state().unwrap(), "cpu").unwrap();
//! for done in 1..=4 {
//!     sim.advance(1).unwrap();
//!     if plan.keeps(done) {
//!         export.record(&sim.read_state().unwrap()).unwrap();
//!     }
//! }
//! let summary = export.finish().unwrap();
//! assert_eq!(summary.frames, 3); // the start and frames 2 and 4
//! std::fs::remove_file(&path).unwrap();
//! ```

#![warn(missing_docs)]

pub mod folder;
pub mod glb;
pub mod read;

use std::io;
use std::path::{Path, PathBuf};

use cloth_core::output;
use cloth_core::{ClothState, Scene, Simulator};

/// What went wrong planning or writing an export. Each names what to change.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The path is neither a `.glb` file nor a folder.
    #[error(
        "cannot export to {path}: give a file ending in .glb (one binary glTF file) or a folder ending in / (OBJ \
         frames and a CSV)"
    )]
    UnknownTarget {
        /// The path given.
        path: PathBuf,
    },
    /// `every` is 0.
    #[error("--every 0: keep every Nth frame with N at least 1")]
    ZeroInterval,
    /// The run does not fit the format's limits.
    #[error(
        "{path}: {frames} frames of {vertices} vertices, one kept every {every}, make {bytes} bytes of binary glTF, \
         more than the format's 4 GiB (a GLB's lengths are 32-bit): at most {fitting} frames fit at --every {every} \
         (lower --frames, raise --every, lower the grid, or export to a folder)"
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Frames asked for.
        frames: u32,
        /// The cloth's vertices.
        vertices: usize,
        /// The interval.
        every: u32,
        /// Bytes it would take.
        bytes: u64,
        /// The most frames that fit at this interval.
        fitting: u64,
    },
    /// A state of another grid than the planned one.
    #[error("a state of {got} vertices given to an export of {expected}")]
    WrongState {
        /// Vertices planned.
        expected: usize,
        /// Vertices given.
        got: usize,
    },
    /// A state with NaN or infinite positions: no format holds it, and it means the step is
    /// unstable.
    #[error(
        "the state at t = {time_s} s has {count} vertices that are NaN or infinite: the step is probably unstable \
         (run `cloth check` and raise the substeps); the export is abandoned"
    )]
    NonFinite {
        /// Simulated time of the state, s.
        time_s: f64,
        /// Vertices not finite.
        count: usize,
    },
    /// More states recorded than planned.
    #[error("more kept frames recorded than the {planned} planned")]
    TooManyFrames {
        /// Kept frames planned.
        planned: u64,
    },
    /// The simulation failed.
    #[error("the simulation failed: {0}")]
    Simulation(#[from] cloth_core::SimError),
    /// Cancelled before it finished: no GLB is left, and a folder has no `diagnostics.csv`.
    #[error("the export to {0} was cancelled before it finished")]
    Cancelled(PathBuf),
    /// A file or folder could not be written; the message names it.
    #[error(transparent)]
    Io(#[from] io::Error),
}

/// Where an export goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ExportTarget {
    /// One binary glTF file.
    Glb(PathBuf),
    /// A folder of OBJ frames, the colliders' OBJ and a CSV (created if missing).
    Folder(PathBuf),
}

impl ExportTarget {
    /// A path ending in `/` (or an existing folder) is a folder; one ending in `.glb` a glTF file.
    ///
    /// # Errors
    /// [`ExportError::UnknownTarget`] for anything else.
    pub fn of(path: &Path) -> Result<Self, ExportError> {
        let text = path.as_os_str().to_string_lossy();
        if text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR) || path.is_dir() {
            return Ok(Self::Folder(path.to_path_buf()));
        }
        match path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()) {
            Some(e) if e == "glb" => Ok(Self::Glb(path.to_path_buf())),
            _ => Err(ExportError::UnknownTarget { path: path.to_path_buf() }),
        }
    }

    /// The file or folder.
    pub fn path(&self) -> &Path {
        match self {
            Self::Glb(p) | Self::Folder(p) => p,
        }
    }
}

/// An export decided before its run: where, which frames, and that they fit.
#[derive(Clone, Debug)]
pub struct ExportPlan {
    /// Where it goes.
    pub target: ExportTarget,
    /// Frames the run simulates.
    pub frames: u32,
    /// Every how many frames one is kept (the start is always kept).
    pub every: u32,
}

impl ExportPlan {
    /// Plans the export of a run of `frames` frames of `scene` to `path`, keeping the start and
    /// every `every`-th frame; checks that the target can be written and that the run fits the
    /// format.
    ///
    /// # Errors
    /// An unknown target, `every` of 0, a run too large for binary glTF (saying how many frames
    /// fit), or a path that cannot be written.
    pub fn new(path: &Path, scene: &Scene, frames: u32, every: u32) -> Result<Self, ExportError> {
        if every == 0 {
            return Err(ExportError::ZeroInterval);
        }
        let plan = Self { target: ExportTarget::of(path)?, frames, every };
        match &plan.target {
            ExportTarget::Glb(path) => {
                glb::check_fits(path, scene, frames, every)?;
                output::check_writable(path)?;
            }
            ExportTarget::Folder(dir) => folder::check_writable(dir)?,
        }
        Ok(plan)
    }

    /// Whether the state after `done` frames (0: the start) is kept.
    pub fn keeps(&self, done: u32) -> bool {
        done.is_multiple_of(self.every)
    }

    /// Kept frames: the start and every `every`-th.
    pub fn kept_frames(&self) -> u64 {
        1 + u64::from(self.frames / self.every)
    }
}

/// A file being written: removed unless [`Temporary::keep`] renames it into place.
pub(crate) struct Temporary {
    pub(crate) path: PathBuf,
    done: bool,
}

impl Temporary {
    pub(crate) fn new(path: PathBuf) -> Self {
        Self { path, done: false }
    }

    /// Renames the complete file to `to` ([`output::rename_into_place`]).
    pub(crate) fn keep(mut self, to: &Path) -> io::Result<()> {
        self.done = true;
        output::rename_into_place(&self.path, to)
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

fn check_finite(state: &ClothState) -> Result<(), ExportError> {
    match state.non_finite_count() {
        0 => Ok(()),
        count => Err(ExportError::NonFinite { time_s: state.time_s, count }),
    }
}

/// What an export wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportSummary {
    /// The file or folder.
    pub path: PathBuf,
    /// Frames kept (the start included).
    pub frames: u64,
    /// Bytes written.
    pub bytes: u64,
}

/// An export under way.
pub enum Exporter {
    /// To one binary glTF file.
    Glb(Box<glb::GlbWriter>),
    /// To a folder of OBJ frames.
    Folder(Box<folder::FolderWriter>),
}

impl Exporter {
    /// Starts the export `plan` of `scene` from the run's first state `initial` (the kept frame
    /// 0), made by the backend named `source` (recorded in the files).
    ///
    /// # Errors
    /// A file that cannot be written (naming it).
    pub fn start(plan: &ExportPlan, scene: &Scene, initial: &ClothState, source: &str) -> Result<Self, ExportError> {
        check_finite(initial)?;
        Ok(match &plan.target {
            ExportTarget::Glb(path) => Self::Glb(Box::new(glb::GlbWriter::start(path, plan, scene, initial, source)?)),
            ExportTarget::Folder(dir) => {
                Self::Folder(Box::new(folder::FolderWriter::start(dir, plan, scene, initial, source)?))
            }
        })
    }

    /// Records the next kept state.
    ///
    /// # Errors
    /// A state of another grid or not finite, more states than planned, or a write that failed.
    pub fn record(&mut self, state: &ClothState) -> Result<(), ExportError> {
        check_finite(state)?;
        match self {
            Self::Glb(w) => w.record(state),
            Self::Folder(w) => w.record(state),
        }
    }

    /// Finishes the files and puts them in place.
    ///
    /// # Errors
    /// A write that failed; nothing is left under the final name.
    pub fn finish(self) -> Result<ExportSummary, ExportError> {
        match self {
            Self::Glb(w) => w.finish(),
            Self::Folder(w) => w.finish(),
        }
    }
}

/// Runs `plan` on `sim` (a fresh simulator of `scene`, at its start): advances it frame by frame,
/// records the kept frames, and calls `on_frame` with the frames done after each; `on_frame`
/// returning `false` cancels the export (its files are removed).
///
/// # Errors
/// A simulation or write failure, or a cancellation; nothing is left under the final name.
pub fn run(
    plan: &ExportPlan,
    scene: &Scene,
    sim: &mut dyn Simulator,
    mut on_frame: impl FnMut(u32) -> bool,
) -> Result<ExportSummary, ExportError> {
    let mut exporter = Exporter::start(plan, scene, &sim.read_state()?, sim.backend_name())?;
    for done in 1..=plan.frames {
        sim.advance(1)?;
        if plan.keeps(done) {
            exporter.record(&sim.read_state()?)?;
        }
        if !on_frame(done) {
            return Err(ExportError::Cancelled(plan.target.path().to_path_buf()));
        }
    }
    exporter.finish()
}
