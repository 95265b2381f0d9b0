//! The order of a frame's dispatches, written once for both backends.
//!
//! | integrator | dispatches per substep |
//! |---|---|
//! | semi-implicit Euler | 1 (`cloth_step`, `STAGE = 0`): on the packed state inside a submission, or fused by the tiled kernel |
//! | velocity Verlet | 2: `STAGE = 1` (kick and drift), `STAGE = 2` (second kick) |
//! | RK4 | 4: `STAGE = 3..=6`, one per stage |
//! | XPBD | `xpbd`: predict; 10 × (one per non-empty colour, the self-contacts, the colliders); finish |
//!
//! With `SelfCollision`, self-collision's check (`self_hash`, one workgroup) comes before every
//! `C`-th substep, counted from the simulation's first, followed by the two indirect dispatches
//! that rebuild the hash and the candidate lists (insert, candidates), whose sizes the check
//! writes: the full sizes when a rebuild is due, zeros otherwise. Before the next
//! substep after the state or the parameters were written, the check always rebuilds
//! (`cloth_core::self_collision` says when a rebuild is due, and why the lists stay correct in
//! between).
//!
//! Every substep reads the state buffer `k` that is current and leaves the new state in buffer
//! `1 − k`; each pass has a bind group per `k`.

use crate::plan::{BindGroupId, PipelineId};

/// One dispatch: a pipeline, its bind group (with the dynamic offset of the layout's dynamic
/// uniform, where it has one) and its workgroups along x and y, or the byte offset in the plan's
/// indirect buffer ([`crate::plan::StateBuffers::indirect`]) where the GPU wrote them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dispatch {
    /// Index into the plan's pipelines.
    pub pipeline: PipelineId,
    /// Index into the plan's bind groups.
    pub bind_group: BindGroupId,
    /// Workgroups along x and y (the most an indirect dispatch may have).
    pub workgroups: [u32; 2],
    /// The dynamic offset, bytes.
    pub dynamic_offset: Option<u32>,
    /// Where the workgroups `(x, y, z)` of an indirect dispatch are, bytes into the indirect
    /// buffer.
    pub indirect: Option<u64>,
}

/// A dispatch of every substep, with its bind group when state buffer `k` is current.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pass {
    /// Index into the plan's pipelines.
    pub pipeline: PipelineId,
    /// The bind group when state `k` is current.
    pub groups: [BindGroupId; 2],
    /// Workgroups along x and y.
    pub workgroups: [u32; 2],
    /// The dynamic offset, bytes.
    pub dynamic_offset: Option<u32>,
    /// Where an indirect dispatch's workgroups are, bytes into the indirect buffer.
    pub indirect: Option<u64>,
}

impl Pass {
    fn on(&self, k: usize) -> Dispatch {
        Dispatch {
            pipeline: self.pipeline,
            bind_group: self.groups[k],
            workgroups: self.workgroups,
            dynamic_offset: self.dynamic_offset,
            indirect: self.indirect,
        }
    }
}

/// Semi-implicit Euler's substeps on its packed state: a submission of `n ≥ 2` substeps runs
/// `first` (the `vec4` state `k` → packed state 0), `n − 2` times `middle` (packed `m` → packed
/// `1 − m`) and `last` (packed `m` → the `vec4` state `1 − k`), so the `vec4` state flips once a
/// submission. Substep `s` takes the blocks backward when `s` is odd (`[forward, backward]`, the
/// same pipeline twice unless the order alternates).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PackedPasses {
    /// `first`'s pipeline.
    pub first_pipeline: PipelineId,
    /// `middle`'s pipelines, forward and backward.
    pub middle_pipelines: [PipelineId; 2],
    /// `last`'s pipelines, forward and backward.
    pub last_pipelines: [PipelineId; 2],
    /// `first`'s bind group when the `vec4` state `k` is current.
    pub first: [BindGroupId; 2],
    /// `middle`'s bind group reading packed state `m`.
    pub middle: [BindGroupId; 2],
    /// `last`'s bind group, `last[k][m]`.
    pub last: [[BindGroupId; 2]; 2],
    /// Workgroups along x and y.
    pub workgroups: [u32; 2],
}

/// The tiled kernel's pass, which advances `substeps` substeps at once.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TiledPass {
    /// The dispatch, from state `k` to `1 − k`.
    pub pass: Pass,
    /// Substeps per dispatch.
    pub substeps: u32,
}

/// Self-collision's check and the indirect dispatches that rebuild its hash and candidate lists
/// from state `k`'s positions, and how many substeps apart the checks come.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SelfCollisionChecks {
    /// The check: orders a rebuild when the candidate lists may be stale.
    pub check: Pass,
    /// The check that always orders one (the first substep, and after a written state).
    pub forced: Pass,
    /// Insert, candidates: indirect.
    pub rebuild: Vec<Pass>,
    /// Substeps between checks, `C` (at least 1).
    pub interval: u32,
}

/// The dispatches of a simulation's frames.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Schedule {
    /// Self-collision's checks and rebuilds, with `SelfCollision` (never with `tiled` or
    /// `packed`).
    pub self_collision: Option<SelfCollisionChecks>,
    /// The dispatches of one substep, in order.
    pub substep: Vec<Pass>,
    /// Semi-implicit Euler's fused substeps, where the tiled kernel runs.
    pub tiled: Option<TiledPass>,
    /// Semi-implicit Euler's packed passes, where they run (never with `tiled`).
    pub packed: Option<PackedPasses>,
}

impl Schedule {
    /// Appends the dispatches of `substeps` substeps starting from state `current` to `out`, and
    /// returns the state current after them: the first substeps of a fresh simulation, whose
    /// self-collision lists, if it has them, are built before the first substep (the forced
    /// check). Later frames continue with [`Schedule::frame_from`].
    pub fn frame(&self, substeps: u64, current: usize, out: &mut Vec<Dispatch>) -> usize {
        self.frame_from(0, true, substeps, current, out)
    }

    /// [`Schedule::frame`] for substeps `first, first + 1, …` of the simulation; `stale`:
    /// self-collision's candidate lists must be rebuilt before the first of them.
    pub fn frame_from(&self, first: u64, stale: bool, substeps: u64, current: usize, out: &mut Vec<Dispatch>) -> usize {
        if let Some(checks) = &self.self_collision {
            let mut k = current;
            for s in 0..substeps {
                let check = if stale && s == 0 {
                    Some(&checks.forced)
                } else {
                    (first + s).is_multiple_of(checks.interval as u64).then_some(&checks.check)
                };
                if let Some(check) = check {
                    out.push(check.on(k));
                    out.extend(checks.rebuild.iter().map(|pass| pass.on(k)));
                }
                out.extend(self.substep.iter().map(|pass| pass.on(k)));
                k = 1 - k;
            }
            return k;
        }
        if let Some(p) = &self.packed
            && substeps >= 2
        {
            let at = |pipeline, bind_group| Dispatch {
                pipeline,
                bind_group,
                workgroups: p.workgroups,
                dynamic_offset: None,
                indirect: None,
            };
            out.push(at(p.first_pipeline, p.first[current]));
            let mut m = 0;
            for s in 1..substeps - 1 {
                out.push(at(p.middle_pipelines[(s % 2) as usize], p.middle[m]));
                m = 1 - m;
            }
            out.push(at(p.last_pipelines[((substeps - 1) % 2) as usize], p.last[current][m]));
            return 1 - current;
        }
        let (mut k, mut left) = (current, substeps);
        while left > 0 {
            // Several substeps in one tiled dispatch where they fit, the rest one at a time.
            match &self.tiled {
                Some(tiled) if left >= tiled.substeps as u64 => {
                    out.push(tiled.pass.on(k));
                    left -= tiled.substeps as u64;
                }
                _ => {
                    out.extend(self.substep.iter().map(|pass| pass.on(k)));
                    left -= 1;
                }
            }
            k = 1 - k;
        }
        k
    }

    /// Substeps one dispatch advances: the tiled kernel's, else 1.
    pub fn fused_substeps(&self) -> u32 {
        self.tiled.as_ref().map_or(1, |t| t.substeps)
    }

    /// Bytes a vertex of the state the substeps hand each other.
    pub fn state_bytes(&self) -> u32 {
        let packed = self.packed.is_some();
        (if packed { crate::geometry::PACKED_VERTEX_BYTES } else { crate::geometry::VEC4_VERTEX_BYTES }) as u32
    }
}
