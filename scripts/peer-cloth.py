#!/usr/bin/env python3
"""Runs NVIDIA Warp's cloth benchmark as a peer of the workbench's own benchmark.

Warp ships one mass-spring cloth benchmark in several implementations
(`warp/examples/benchmarks/benchmark_cloth*.py` inside the warp-lang package). This driver
imports those modules from the installed Warp and runs their integrators on the same cloth at
chosen grid sides and substep counts, one warm-up frame and then timed frames, and prints one CSV
row per run on standard output:

    peer,grid,substeps,frames,ms_per_frame,vertex_substeps_per_s,springs

Peers (`--backends`):
  warp        Warp's kernels, launched one by one from Python (two launches a substep)
  warp-graph  the same Warp kernels, each frame's substeps captured once in a CUDA graph and
              replayed as one graph launch a frame
  cupy        the CuPy version
  torch       the PyTorch version

What a timed frame is (`--readback`):
  none    the substeps' GPU work only: frames are issued back to back and the host waits once,
          after the last one (the shape of the workbench's own `cloth bench`); rows are named
          after the peer
  frame   the benchmark's own frame: the substeps, then a copy of every position to host memory
          and a wait, as Warp's `benchmark_cloth.py` times it; rows are named `PEER+readback`
  both    both of the above, one after the other (the default)

ms_per_frame is wall-clock time from a synchronised start to a synchronised end, divided by the
frame count; vertex_substeps_per_s is grid² × substeps / seconds per frame.

The cloth is the benchmark's own: Warp's `Cloth` class is read from `benchmark_cloth.py` (its
class definition only, so the module's own benchmark run and its USD import are not executed),
with the parameters that `benchmark_cloth.run_benchmark` passes to it. Its spring list comes from
Python loops that take tens of seconds at 1024², so the driver builds the same arrays with
vectorised numpy and, before any run, checks them element for element against Warp's class at a
small grid (`--check-springs`). `--builder python` uses Warp's class at every grid instead.

Usage (with warp-lang, and CuPy or PyTorch for those peers, importable):
    python3 scripts/peer-cloth.py --grids 128,1024 --substeps 16,64 --frames 60 \
        --backends warp,warp-graph,cupy,torch
"""

import argparse
import ast
import importlib
import os
import sys
import time
import types

import numpy as np

# The arguments that Warp's `benchmark_cloth.run_benchmark` gives the cloth and its integrators.
BENCH_FPS = 60.0
BENCH_SUBSTEPS = 16
BENCH_FRAMES = 60
BENCH_GRIDS = (32, 64, 128)
CLOTH_LOWER = (0.0, 0.0, 0.0)
CLOTH_SPACING = 0.1  # the `radius` argument: the distance between grid neighbours, metres
K_STRETCH = 1000.0
K_SHEAR = 1000.0
K_BEND = 1000.0
VERTEX_MASS = 0.1
FIX_CORNERS = True
# `Cloth.__init__` gives every spring its `create_spring` default damping (the benchmark's own
# `k_damp` is never passed on); the spring check below confirms the value against Warp's class.
SPRING_DAMPING = 10.0

CSV_HEADER = "peer,grid,substeps,frames,ms_per_frame,vertex_substeps_per_s,springs"
PEERS = ("warp", "warp-graph", "cupy", "torch")


class PeerError(Exception):
    """A condition that stops the run with a message instead of a traceback."""


def log(message):
    print(f"peer-cloth: {message}", file=sys.stderr, flush=True)


def parse_int_list(text):
    try:
        values = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}")
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive integers, got {text!r}")
    return values


def parse_backends(text):
    names = [part.strip() for part in text.split(",") if part.strip()]
    unknown = [name for name in names if name not in PEERS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown backend(s) {unknown}; choose from {','.join(PEERS)}")
    return names


# ---------------------------------------------------------------------------------------------
# Warp's benchmark modules


def benchmarks_dir(explicit):
    """The folder that holds Warp's benchmark_cloth*.py."""
    if explicit:
        folder = explicit
    else:
        try:
            import warp
        except ImportError as error:
            raise PeerError(f"cannot import warp ({error}); put warp-lang on PYTHONPATH") from error
        folder = os.path.join(os.path.dirname(os.path.abspath(warp.__file__)), "examples", "benchmarks")
    if not os.path.isfile(os.path.join(folder, "benchmark_cloth.py")):
        raise PeerError(f"no benchmark_cloth.py in {folder}")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    return folder


def warp_cloth_class(folder):
    """Warp's `Cloth` class, taken from benchmark_cloth.py without running the rest of that file.

    The file runs its benchmark and imports USD at module level, so only its `Cloth` class
    definition is compiled and executed, with numpy as the `np` it refers to.
    """
    path = os.path.join(folder, "benchmark_cloth.py")
    with open(path, encoding="utf-8") as source:
        tree = ast.parse(source.read(), filename=path)
    classes = [node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "Cloth"]
    if len(classes) != 1:
        raise PeerError(f"expected one `class Cloth` in {path}")
    namespace = {"np": np, "__name__": "benchmark_cloth"}
    exec(compile(ast.Module(body=classes, type_ignores=[]), path, "exec"), namespace)
    return namespace["Cloth"]


def import_benchmark(name):
    try:
        return importlib.import_module(name)
    except ImportError as error:
        raise PeerError(f"cannot import {name} ({error})") from error


# ---------------------------------------------------------------------------------------------
# The cloth


def build_cloth_with_warp_class(cloth_class, n):
    return cloth_class(
        lower=CLOTH_LOWER,
        dx=n,
        dy=n,
        radius=CLOTH_SPACING,
        stretch_stiffness=K_STRETCH,
        bend_stiffness=K_BEND,
        shear_stiffness=K_SHEAR,
        mass=VERTEX_MASS,
        fix_corners=FIX_CORNERS,
    )


def build_cloth_numpy(n):
    """The benchmark cloth's arrays at n × n, in the same order as Warp's `Cloth` produces them.

    Vertex `y * n + x` sits at lower + spacing · (x, 0, y). Springs come in two passes:
    a row-major pass over the vertices with, for each, the spring to x - 1 (stretch), to x - 2
    (bend), to (x + 1, y - 1) and to (x - 1, y - 1) (shear), each where it exists; then a
    column-major pass (x outer, y inner) with the springs to y - 1 (stretch) and y - 2 (bend).
    Rest lengths are float64 distances rounded to float32. The two vertices of the first row's
    ends are pinned (inverse mass 0).
    """
    xs = np.arange(n, dtype=np.int64)
    gy, gx = np.meshgrid(xs, xs, indexing="ij")  # [y, x]
    index = gy * n + gx

    grid = np.stack([gx, np.zeros_like(gx), gy], axis=-1).reshape(-1, 3).astype(np.float64)
    positions64 = np.asarray(CLOTH_LOWER, dtype=np.float64) + CLOTH_SPACING * grid

    inv_masses = np.full(n * n, 1.0 / VERTEX_MASS, dtype=np.float64)
    if FIX_CORNERS:
        inv_masses[0] = 0.0
        inv_masses[n - 1] = 0.0

    # Row-major pass: four candidate springs a vertex.
    row_other = np.stack(
        [index - 1, index - 2, index - n + 1, index - n - 1], axis=-1
    )  # [y, x, 4]
    row_valid = np.stack(
        [
            gx > 0,
            (gx > 1) & (K_BEND > 0.0),
            (gy > 0) & (gx < n - 1) & (K_SHEAR > 0.0),
            (gy > 0) & (gx > 0) & (K_SHEAR > 0.0),
        ],
        axis=-1,
    )
    row_k = np.broadcast_to(np.array([K_STRETCH, K_BEND, K_SHEAR, K_SHEAR]), row_other.shape)
    row_self = np.broadcast_to(index[..., None], row_other.shape)

    # Column-major pass: two candidate springs a vertex, x outer and y inner.
    col_index = index.T  # [x, y]
    col_y = gy.T
    col_other = np.stack([col_index - n, col_index - 2 * n], axis=-1)
    col_valid = np.stack([col_y > 0, (col_y > 1) & (K_BEND > 0.0)], axis=-1)
    col_k = np.broadcast_to(np.array([K_STRETCH, K_BEND]), col_other.shape)
    col_self = np.broadcast_to(col_index[..., None], col_other.shape)

    first = np.concatenate([row_self[row_valid], col_self[col_valid]])
    second = np.concatenate([row_other[row_valid], col_other[col_valid]])
    stiffness = np.concatenate([row_k[row_valid], col_k[col_valid]])

    delta = positions64[first] - positions64[second]
    lengths = np.sqrt(np.einsum("ij,ij->i", delta, delta))

    pairs = np.empty(2 * len(first), dtype=np.int32)
    pairs[0::2] = first
    pairs[1::2] = second

    cloth = types.SimpleNamespace()
    cloth.positions = positions64.astype(np.float32)
    cloth.velocities = np.zeros((n * n, 3), dtype=np.float32)
    cloth.inv_masses = inv_masses.astype(np.float32)
    cloth.spring_indices = pairs
    cloth.spring_lengths = lengths.astype(np.float32)
    cloth.spring_stiffness = stiffness.astype(np.float32)
    cloth.spring_damping = np.full(len(first), SPRING_DAMPING, dtype=np.float32)
    cloth.num_particles = n * n
    cloth.num_springs = len(first)
    cloth.num_tris = 2 * (n - 1) * (n - 1)
    return cloth


CLOTH_ARRAYS = (
    "positions",
    "velocities",
    "inv_masses",
    "spring_indices",
    "spring_lengths",
    "spring_stiffness",
    "spring_damping",
)


def compare_cloths(reference, candidate):
    """The names of the arrays or counts that differ (dtype, shape or any element)."""
    differing = []
    for name in CLOTH_ARRAYS:
        a = getattr(reference, name)
        b = getattr(candidate, name)
        if a.dtype != b.dtype or a.shape != b.shape or not np.array_equal(a, b):
            differing.append(name)
    for name in ("num_particles", "num_springs"):
        if getattr(reference, name) != getattr(candidate, name):
            differing.append(name)
    return differing


def check_spring_builder(cloth_class, n):
    start = time.perf_counter()
    reference = build_cloth_with_warp_class(cloth_class, n)
    ours = build_cloth_numpy(n)
    differing = compare_cloths(reference, ours)
    if differing:
        raise PeerError(f"the numpy cloth differs from Warp's Cloth at {n}x{n} in: {', '.join(differing)}")
    log(
        f"numpy cloth matches Warp's Cloth at {n}x{n} ({ours.num_springs} springs, identical arrays, "
        f"{time.perf_counter() - start:.2f} s)"
    )


# ---------------------------------------------------------------------------------------------
# Peers


class WarpPeer:
    """Warp's `WpIntegrator`; with `graph`, each frame's substeps replay one captured CUDA graph."""

    def __init__(self, module, cloth, device, graph):
        import warp as wp

        self.wp = wp
        self.module = module
        self.integrator = module.WpIntegrator(cloth, device)
        self.device = self.integrator.device
        self.graph_wanted = graph
        self.graph = None
        self.graph_key = None

    def _launch_substeps(self, dt, substeps):
        wp = self.wp
        it = self.integrator
        sub_dt = dt / substeps
        for _ in range(substeps):
            wp.launch(
                kernel=self.module.eval_springs,
                dim=it.cloth.num_springs,
                inputs=[
                    it.positions,
                    it.velocities,
                    it.spring_indices,
                    it.spring_lengths,
                    it.spring_stiffness,
                    it.spring_damping,
                    it.forces,
                ],
                device=self.device,
            )
            wp.launch(
                kernel=self.module.integrate_particles,
                dim=it.cloth.num_particles,
                inputs=[it.positions, it.velocities, it.forces, it.invmass, sub_dt],
                device=self.device,
            )

    def _graph_for(self, dt, substeps):
        wp = self.wp
        key = (dt, substeps)
        if self.graph_key != key:
            wp.load_module(self.module, device=self.device)
            wp.capture_begin(device=self.device, force_module_load=False)
            try:
                self._launch_substeps(dt, substeps)
            finally:
                self.graph = wp.capture_end(device=self.device)
            self.graph_key = key
        return self.graph

    def frame(self, dt, substeps, readback):
        wp = self.wp
        if not self.graph_wanted:
            if readback:
                self.integrator.simulate(dt, substeps)
            else:
                self._launch_substeps(dt, substeps)
            return
        wp.capture_launch(self._graph_for(dt, substeps))
        if readback:
            wp.copy(self.integrator.positions_host, self.integrator.positions)
            wp.synchronize()
            self.integrator.positions_host.numpy()

    def prepare(self, dt, substeps):
        if self.graph_wanted:
            self._graph_for(dt, substeps)

    def sync(self):
        self.wp.synchronize_device(self.device)

    def positions(self):
        return self.integrator.positions.numpy()


def array_substeps(module, it, dt, substeps, integrate_args):
    """One frame of the CuPy or PyTorch version without its read-back: `substeps` calls of the
    module's `eval_springs` and `integrate_particles` (whose arguments, which differ between the
    two modules, `integrate_args(sub_dt)` gives)."""
    sub_dt = dt / substeps
    pairs = it.spring_indices.reshape((it.cloth.num_springs, 2))
    for _ in range(substeps):
        module.eval_springs(
            it.positions, it.velocities, pairs, it.spring_lengths, it.spring_stiffness, it.spring_damping, it.forces
        )
        module.integrate_particles(*integrate_args(sub_dt))


class CupyPeer:
    """Warp's CuPy version, `CpIntegrator`."""

    def __init__(self, module, cloth):
        import cupy

        self.cp = cupy
        self.module = module
        self.integrator = module.CpIntegrator(cloth)

    def frame(self, dt, substeps, readback):
        if readback:
            self.integrator.simulate(dt, substeps)
            return
        it = self.integrator
        array_substeps(self.module, it, dt, substeps, lambda h: (it.positions, it.velocities, it.forces, it.inv_mass, h))

    def prepare(self, dt, substeps):
        pass

    def sync(self):
        self.cp.cuda.Device().synchronize()

    def positions(self):
        return self.cp.asnumpy(self.integrator.positions)


class TorchPeer:
    """Warp's PyTorch version, `TrIntegrator`."""

    def __init__(self, module, cloth, device):
        import torch

        self.torch = torch
        self.module = module
        self.device = device
        self.integrator = module.TrIntegrator(cloth, device)

    def frame(self, dt, substeps, readback):
        if readback:
            self.integrator.simulate(dt, substeps)
            return
        it = self.integrator
        array_substeps(
            self.module, it, dt, substeps, lambda h: (it.positions, it.velocities, it.forces, it.gravity, it.inv_mass, h)
        )

    def prepare(self, dt, substeps):
        pass

    def sync(self):
        if self.device != "cpu":
            self.torch.cuda.synchronize()

    def positions(self):
        return self.integrator.positions.cpu().numpy()


# ---------------------------------------------------------------------------------------------
# Set-up of each peer's library


def setup_warp(device, kernel_cache, verbose):
    try:
        import warp as wp
    except ImportError as error:
        raise PeerError(f"cannot import warp ({error}); put warp-lang on PYTHONPATH") from error
    wp.config.quiet = not verbose
    if kernel_cache:
        wp.config.kernel_cache_dir = kernel_cache
    # benchmark_cloth_warp initialises Warp and clears its kernel cache when imported.
    module = import_benchmark("benchmark_cloth_warp")
    if device == "cuda":
        if not wp.is_cuda_available():
            raise PeerError(
                "CUDA is not available to Warp (no CUDA driver or device found); "
                "the warp peers need an NVIDIA GPU"
            )
        cuda = wp.get_device("cuda")
        log(f"warp {wp.config.version} on {cuda.name} (sm_{cuda.arch})")
    elif not wp.is_cpu_available():
        raise PeerError("Warp's CPU backend is not available (warp/bin/warp-clang.so is missing)")
    return module


def setup_cupy():
    try:
        import cupy
        import cupyx
    except ImportError as error:
        raise PeerError(f"cannot import cupy ({error})") from error
    try:
        count = cupy.cuda.runtime.getDeviceCount()
    except Exception as error:  # CuPy raises its own CUDA runtime errors here
        raise PeerError(f"CUDA is not available to CuPy ({error})") from error
    if count < 1:
        raise PeerError("CUDA is not available to CuPy (no device)")
    if not hasattr(cupyx, "scatter_add"):
        # The CuPy version calls cupyx.scatter_add, which CuPy deprecates in favour of cupy.add.at;
        # where it is gone, cupy.add.at stands in for it.
        cupyx.scatter_add = lambda a, slices, value: cupy.add.at(a, slices, value)
        log("cupyx.scatter_add is missing: using cupy.add.at in its place")
    props = cupy.cuda.runtime.getDeviceProperties(cupy.cuda.Device().id)
    name = props["name"].decode() if isinstance(props["name"], bytes) else props["name"]
    log(f"cupy {cupy.__version__} on {name}")
    return import_benchmark("benchmark_cloth_cupy")


def setup_torch(device):
    try:
        import torch
    except ImportError as error:
        raise PeerError(f"cannot import torch ({error})") from error
    if device == "cuda":
        if not torch.cuda.is_available():
            raise PeerError("CUDA is not available to PyTorch (torch.cuda.is_available() is False)")
        log(f"torch {torch.__version__} on {torch.cuda.get_device_name()}")
    return import_benchmark("benchmark_cloth_pytorch")


# ---------------------------------------------------------------------------------------------
# Running


def time_run(peer, dt, substeps, frames, readback):
    """Seconds per frame after one warm-up frame, from a synchronised start to a synchronised end."""
    peer.prepare(dt, substeps)
    peer.frame(dt, substeps, readback)
    peer.sync()
    start = time.perf_counter()
    for _ in range(frames):
        peer.frame(dt, substeps, readback)
    peer.sync()
    return (time.perf_counter() - start) / frames


def main(argv=None):
    parser = argparse.ArgumentParser(
        description="Run NVIDIA Warp's cloth benchmark (Warp, CuPy and PyTorch versions) and print CSV rows.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n\n", 1)[1],
    )
    parser.add_argument("--grids", type=parse_int_list, default=list(BENCH_GRIDS),
                        help="grid sides N, comma-separated (default: the benchmark's 32,64,128)")
    parser.add_argument("--substeps", type=parse_int_list, default=[BENCH_SUBSTEPS],
                        help=f"substeps per frame, comma-separated (default: the benchmark's {BENCH_SUBSTEPS})")
    parser.add_argument("--frames", type=int, default=BENCH_FRAMES,
                        help=f"timed frames per run, after one warm-up frame (default: the benchmark's {BENCH_FRAMES})")
    parser.add_argument("--backends", type=parse_backends, default=list(PEERS),
                        help=f"peers, comma-separated from {','.join(PEERS)} (default: all)")
    parser.add_argument("--readback", choices=("none", "frame", "both"), default="both",
                        help="what a timed frame includes (default: both, one run each)")
    parser.add_argument("--builder", choices=("numpy", "python"), default="numpy",
                        help="numpy: vectorised arrays identical to Warp's Cloth; python: Warp's Cloth itself (slow)")
    parser.add_argument("--check-springs", type=int, default=24, metavar="N",
                        help="compare the numpy cloth with Warp's Cloth at N x N before running (0: skip; default 24)")
    parser.add_argument("--device", choices=("cuda", "cpu"), default="cuda",
                        help="cuda (default); cpu runs the warp and torch peers on the CPU, as a check of this "
                             "driver on machines without a GPU, not as a benchmark")
    parser.add_argument("--benchmarks-dir", default=None,
                        help="folder with Warp's benchmark_cloth*.py (default: the one inside the imported warp)")
    parser.add_argument("--kernel-cache", default=None,
                        help="Warp's kernel cache folder (default: Warp's own choice)")
    parser.add_argument("--no-header", action="store_true", help="do not print the CSV header")
    parser.add_argument("--verbose", action="store_true", help="let Warp print its initialisation and compile messages")
    args = parser.parse_args(argv)

    if args.frames < 1:
        parser.error("--frames must be at least 1")
    if args.device == "cpu":
        refused = [b for b in args.backends if b in ("warp-graph", "cupy")]
        if refused:
            parser.error(f"{','.join(refused)} need CUDA; --device cpu runs only warp and torch")

    try:
        folder = benchmarks_dir(args.benchmarks_dir)
        cloth_class = warp_cloth_class(folder)
        if args.check_springs > 0 and args.builder == "numpy":
            check_spring_builder(cloth_class, args.check_springs)

        modules = {}
        if any(b.startswith("warp") for b in args.backends):
            modules["warp"] = setup_warp(args.device, args.kernel_cache, args.verbose)
        if "cupy" in args.backends:
            modules["cupy"] = setup_cupy()
        if "torch" in args.backends:
            modules["torch"] = setup_torch(args.device)

        modes = {"none": [False], "frame": [True], "both": [False, True]}[args.readback]
        dt = 1.0 / BENCH_FPS

        if not args.no_header:
            print(CSV_HEADER, flush=True)

        for n in args.grids:
            start = time.perf_counter()
            if args.builder == "numpy":
                cloth = build_cloth_numpy(n)
            else:
                cloth = build_cloth_with_warp_class(cloth_class, n)
            log(f"cloth {n}x{n}: {cloth.num_particles} vertices, {cloth.num_springs} springs, "
                f"built in {time.perf_counter() - start:.2f} s")

            for substeps in args.substeps:
                for backend in args.backends:
                    for readback in modes:
                        if backend in ("warp", "warp-graph"):
                            peer = WarpPeer(modules["warp"], cloth, args.device, graph=(backend == "warp-graph"))
                        elif backend == "cupy":
                            peer = CupyPeer(modules["cupy"], cloth)
                        else:
                            peer = TorchPeer(modules["torch"], cloth, args.device)

                        seconds = time_run(peer, dt, substeps, args.frames, readback)
                        final = peer.positions()
                        if not np.all(np.isfinite(final)):
                            log(f"{backend} {n}x{n} x {substeps}: positions are not finite after the run")
                        label = backend + ("+readback" if readback else "")
                        rate = cloth.num_particles * substeps / seconds
                        print(
                            f"{label},{n},{substeps},{args.frames},{seconds * 1e3:.6f},{rate:.6e},{cloth.num_springs}",
                            flush=True,
                        )
                        del peer
    except PeerError as error:
        print(f"peer-cloth: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
