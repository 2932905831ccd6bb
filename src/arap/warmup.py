"""The compiled (numba) kernels: warm them up before timing anything, where their machine code is cached, and
whether a background warm-up still compiles them.

numba compiles a kernel on its first call (seconds for the whole set) and, as every kernel is declared with
``cache=True``, stores the machine code for later processes: in ``__pycache__`` next to the modules when that folder
is writable, else in the user's cache folder (``~/.cache/numba``), or in ``NUMBA_CACHE_DIR`` when it is set. So only
the first run in a new environment (or after an update of arap or numba) pays for compilation.

>>> from arap.warmup import warm_up_kernels
>>> warm_up_kernels().compiled     # doctest: +SKIP
0
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:
    from arap.options import Acceleration, EnergyType

__all__ = ["EVERY_SOLVE_ITERATIONS", "EVERY_SOLVE_KERNELS", "FIRST_KERNELS", "KERNELS_READY", "LATER_KERNELS",
           "CompileProgress", "KernelWarmUp", "compile_progress", "compile_reporter", "warm_up_every_solve",
           "warm_up_kernels"]

KERNELS_READY = threading.Event()
"""Set unless a warm-up runs in the background (``arap studio`` serves the page while the kernels compile): the studio
server greets a new connection once it is set, so that the page says the solver is being prepared instead of
hanging on its first drag."""
KERNELS_READY.set()

FIRST_KERNELS = (
    "arap.meshes._geometry._double_areas",
    "arap.meshes.topology._face_adjacency",
    "arap.meshes.topology._free_components",
    "arap.meshes._geometry._barycentric_areas",
    "arap.method.weights._cotangent_kernel",
    "arap.method.cells._rim_cells_kernel",
    "arap.method.cells._rest_edges",
    "arap.sparse._csr._terms_to_csr",
    "arap.sparse._csr._leading_blocks",
    "arap.method.cells._gather_kernel",
    "arap.method.local_step._local_serial",
    "arap.solve.indexing._with_rows",
    "arap.method.inactive._changed_rows",
    "arap.method.inactive._rigid_fit_miss",
    "arap.sparse._csr._rows_product",
    "arap.method.local_step._rhs_gradient_serial",
    "arap.solve.lbfgs._subtract_sq_place",
    "arap.solve.indexing._rows_of",
)
"""The kernels a session needs first (loading a mesh, solving it on one thread), in the order the warm-up's first
solve compiles them (the kernels they call are compiled with them)."""
LATER_KERNELS = (
    "arap.method.local_step._local_parallel",
    "arap.method.local_step._rhs_gradient_parallel",
)
"""The threaded variants that only large meshes run, compiled after :data:`FIRST_KERNELS`."""
EVERY_SOLVE_KERNELS: tuple[str, ...] = (
    "arap.solve.lbfgs._diff_dot",
    "arap.solve.lbfgs._pair",
    "arap.solve.lbfgs._dot",
    "arap.solve.lbfgs._axpy",
    "arap.solve.lbfgs._axpy_dot",
    "arap.solve.lbfgs._subtract_sq",
    "arap.method.local_step._rhs_serial",
    "arap.solve.lbfgs._difference_sq",
    "arap.method.smooth._covariances_serial",
    "arap.method.rotation_step._energy_serial",
    "arap.method.rotation_step._rotate_serial",
    "arap.method.smooth._sweep_serial",
    "arap.method.smooth._rotation_term_serial",
    "arap.method.planar.planar_local_serial",
    "arap.method.planar._rhs_gradient_serial",
    "arap.method.planar._rhs_serial",
    "arap.method.local_step._rhs_parallel",
    "arap.method.smooth._covariances_parallel",
    "arap.method.rotation_step._energy_parallel",
    "arap.method.rotation_step._rotate_parallel",
    "arap.method.smooth._sweep_parallel",
    "arap.method.smooth._rotation_term_parallel",
    "arap.method.planar.planar_local_parallel",
    "arap.method.planar._rhs_gradient_parallel",
    "arap.method.planar._rhs_parallel",
    "arap.puppet.blend._similarity_serial",
    "arap.puppet.blend._similarity_parallel",
)
"""The kernels that only the other energies, accelerations, the warp modes of pictures (the similarity step of the
Normal and Distort modes, :func:`arap.puppet.blend.similarity_step`) and the energy and distortion of a result run,
serial and threaded, compiled by :func:`warm_up_every_solve` after :data:`LATER_KERNELS`."""
EVERY_SOLVE_ITERATIONS = 12
"""Iterations of each solve of :func:`warm_up_every_solve`: enough for L-BFGS to take its own steps after the plain
ones it starts with."""


@dataclass(frozen=True)
class CompileProgress:
    """Where a warm-up (:func:`warm_up_kernels`) stands.

    Attributes
    ----------
    done, total : int
        Kernels of :data:`FIRST_KERNELS` and :data:`LATER_KERNELS` (and of :data:`EVERY_SOLVE_KERNELS` in a warm-up
        of every energy) ready (compiled or loaded from the cache), of all.
    kernel : str or None
        Name of the kernel being compiled now (``compiling``), else of the one compiled last (None before any).
    compiling : bool
        Whether ``kernel`` is being compiled now.
    seconds : float
        Time since the warm-up started (0 when none has).
    """

    done: int
    total: int
    kernel: str | None
    compiling: bool
    seconds: float

    def describe(self) -> str:
        """One line: ``"5 of 20 kernels ready (compiling _free_components), 14 s"``."""
        now = f" ({'compiling' if self.compiling else 'compiled'} {self.kernel})" if self.kernel else ""
        return f"{self.done} of {self.total} kernels ready{now}, {self.seconds:.0f} s"


_started: float | None = None
_compiling: list[str] = []  # names of the kernels being compiled, outermost first
_last: list[str] = []  # the kernel compiled last
_kernels: list[str] = [*FIRST_KERNELS, *LATER_KERNELS]  # those the warm-up under way compiles (its progress's total)
_state_lock = threading.Lock()


def _all_kernels(every_energy: bool) -> tuple[str, ...]:
    """The kernels a warm-up compiles, in their order: those of every solve too with ``every_energy``."""
    return FIRST_KERNELS + LATER_KERNELS + (EVERY_SOLVE_KERNELS if every_energy else ())


def _kernel_ready(qualified: str) -> bool:
    module, _, name = qualified.rpartition(".")
    dispatcher = getattr(sys.modules.get(module), name, None)
    return bool(getattr(dispatcher, "overloads", None))


def compile_progress() -> CompileProgress:
    """Where the warm-up stands now (:class:`CompileProgress`); callable from any thread."""
    with _state_lock:
        kernels = tuple(_kernels)
        kernel = _compiling[0] if _compiling else (_last[0] if _last else None)
        compiling = bool(_compiling)
        seconds = 0.0 if _started is None else time.perf_counter() - _started
    return CompileProgress(done=sum(_kernel_ready(k) for k in kernels), total=len(kernels), kernel=kernel,
                           compiling=compiling, seconds=seconds)


def _compile_listener(progress: Callable[[CompileProgress], None] | None) -> Any:
    """A numba event listener that keeps the name of the kernel being compiled, and calls ``progress`` when one of
    those a solve calls (not one they call) is compiled."""
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev: Any) -> None:
            with _state_lock:
                _compiling.append(ev.data["dispatcher"].py_func.__name__)

        def on_end(self, ev: Any) -> None:
            with _state_lock:
                if _compiling:
                    _last[:] = [_compiling.pop()]
                outermost = not _compiling
            if outermost and progress is not None:
                progress(compile_progress())

    return Listener()


@dataclass(frozen=True)
class KernelWarmUp:
    """What :func:`warm_up_kernels` did.

    Attributes
    ----------
    seconds : float
        Wall time of the warm-up (compiling, or loading from the cache, plus a tiny solve).
    compiled : int
        Kernel signatures compiled now (0 when everything came from the cache).
    loaded : int
        Kernel signatures loaded from the cache.
    cache_dir : str or None
        Folder of the cached machine code of the first kernel (None when caching is off).
    """

    seconds: float
    compiled: int
    loaded: int
    cache_dir: str | None

    def record(self) -> dict[str, object]:
        """What a JSON report says of the warm-up: whether it compiled, its seconds and the cache folder."""
        return {"compiled": self.compiled > 0, "seconds": self.seconds, "cache_dir": self.cache_dir}


def _dispatchers() -> list[Any]:
    """The numba dispatchers defined in arap's loaded modules."""
    from numba.core.dispatcher import Dispatcher

    found: dict[int, Any] = {}
    for name, module in list(sys.modules.items()):
        if module is None or not (name == "arap" or name.startswith("arap.")):
            continue
        for value in vars(module).values():
            if isinstance(value, Dispatcher):
                found[id(value)] = value
    return list(found.values())


def _counts() -> tuple[int, int]:
    hits = misses = 0
    for dispatcher in _dispatchers():
        stats = dispatcher.stats
        hits += sum(stats.cache_hits.values())
        misses += sum(stats.cache_misses.values())
    return hits, misses


def warm_up_kernels(quiet: bool = True, progress: Callable[[CompileProgress], None] | None = None,
                    first_ready: Callable[[], None] | None = None, every_energy: bool = False) -> KernelWarmUp:
    """Compile (or load from the cache) every kernel a solve uses, with tiny solves on a 42-vertex sphere (serial,
    then with the threaded variants that large meshes use).

    The kernels take the same argument types for every mesh and weighting, so after this no solve of the default
    energy (or of ``spokes``) compiles anything and its timings are those of the iterations alone; with
    ``every_energy``, no solve at all (``arap warmup``). The lower half of the sphere is fixed, so that some cells
    see only constrained vertices (their energy is computed once, with the same kernel).

    Parameters
    ----------
    quiet : bool
        False: say on stderr how far the compilation is every few seconds (unless ``progress`` is given) and, when
        kernels were compiled, how long it took and where they are cached (the command line's note before timing
        anything).
    progress : callable or None
        ``progress(CompileProgress)`` each time a kernel has been compiled (never when all come from the cache);
        :func:`compile_progress` tells the same from any thread.
    first_ready : callable or None
        Called once the kernels a session needs first (:data:`FIRST_KERNELS`) are ready, before the threaded
        variants (:data:`LATER_KERNELS`) are compiled.
    every_energy : bool
        Also compile what every other choice a user can make runs (:func:`warm_up_every_solve`): each energy, the
        element energies of planar meshes and of tetrahedra included, with each acceleration, and the energy and
        distortion of a result. Their kernels (:data:`EVERY_SOLVE_KERNELS`) then count in the progress too.

    Returns
    -------
    KernelWarmUp
    """
    from numba.core import event

    global _started
    with _state_lock:
        _started = time.perf_counter()
        _kernels[:] = _all_kernels(every_energy)
    if progress is None and not quiet:
        progress = compile_reporter()
    try:
        with event.install_listener("numba:compile", _compile_listener(progress)):
            warm = _warm_up(first_ready, every_energy)
    finally:
        with _state_lock:
            _kernels[:] = _all_kernels(False)
    if warm.compiled and not quiet:
        where = f"cached in {warm.cache_dir}"
        sys.stderr.write(f"arap: compiling kernels (first run only)… {warm.seconds:.1f} s ({where})\n")
        sys.stderr.flush()
    return warm


def compile_reporter(every: float = 5.0) -> Callable[[CompileProgress], None]:
    """A ``progress`` for :func:`warm_up_kernels` that writes to stderr how many kernels are ready, by name, at most
    every ``every`` seconds (and when the last is)."""
    last = [-math.inf]

    def report(progress: CompileProgress) -> None:
        now = time.monotonic()
        if progress.done < progress.total and now - last[0] < every:
            return
        last[0] = now
        sys.stderr.write(f"arap: compiling the solver's kernels: {progress.describe()}\n")
        sys.stderr.flush()

    return report


def _warm_up(first_ready: Callable[[], None] | None, every_energy: bool = False) -> KernelWarmUp:
    from arap.kernels.parallel import policy
    from arap.meshes.shapes import sphere
    from arap.solve.solver import ArapSolver

    t0 = time.perf_counter()
    hits0, misses0 = _counts()
    V, F = sphere(frequency=2)
    fixed = np.flatnonzero(V[:, 2] < 0.0)
    handle = np.array([int(np.argmax(V[:, 2]))])
    constrained = np.concatenate([fixed, handle])
    targets = np.concatenate([V[fixed], V[handle] + [0.1, 0.0, 0.0]])
    ArapSolver(V, F, constrained).solve(targets, max_iterations=2)
    if first_ready is not None:
        first_ready()
    # The paper's spokes energy assembles its cells from the edge weight matrix, which the default energy does not.
    ArapSolver(V, F, constrained, energy="spokes").solve(targets, max_iterations=2)
    # Large meshes run the threaded variants: make the size rule pick them for this tiny solve too.
    with policy.every_kernel_threaded():
        ArapSolver(V, F, constrained).solve(targets, max_iterations=2)
    if every_energy:
        warm_up_every_solve()
    hits, misses = _counts()
    paths = [d.stats.cache_path for d in _dispatchers() if d.stats.cache_path]
    warm = KernelWarmUp(seconds=time.perf_counter() - t0, compiled=misses - misses0, loaded=hits - hits0,
                        cache_dir=paths[0] if paths else None)
    return warm


def warm_up_every_solve() -> None:
    """Solve a 42-vertex sphere, a planar rectangle and a box of tetrahedra with every energy each takes
    (:data:`~arap.options.ENERGY_TYPES`) and every acceleration (:data:`~arap.options.ACCELERATIONS`), and ask for the
    energy and the distortion of each result, and warp a tiny picture in each of the puppet warp's modes
    (:func:`_picture_solves`): serial, then with the threaded variants of large meshes. What :func:`warm_up_kernels`
    compiles with ``every_energy`` after the default solves (``arap warmup``).
    """
    from arap.errors import OptionError
    from arap.kernels.parallel import policy
    from arap.meshes.grids import box_tetrahedra, rectangle_triangles
    from arap.meshes.shapes import sphere
    from arap.method.energy import arap_energy, cell_distortion
    from arap.options import ACCELERATIONS, ENERGY_TYPES
    from arap.solve.solver import ArapSolver

    meshes = (sphere(frequency=2), rectangle_triangles(4, 2), box_tetrahedra(2, 1, 1))

    def solves() -> None:
        for V, F in meshes:
            fixed = np.flatnonzero(V[:, 0] < V[:, 0].min() + 0.25 * np.ptp(V[:, 0]))
            handle = np.array([int(np.argmax(V[:, 0]))])
            targets = np.concatenate([V[fixed], V[handle] + 0.1 * np.ptp(V[:, 0])])
            for energy in cast("tuple[EnergyType, ...]", ENERGY_TYPES):
                try:
                    solver = ArapSolver(V, F, np.concatenate([fixed, handle]), energy=energy)
                except OptionError:  # an energy this kind of mesh does not take (smooth rotations of a plane)
                    continue
                for acceleration in cast("tuple[Acceleration, ...]", ACCELERATIONS):
                    solver.reset()
                    U = solver.solve(targets, max_iterations=EVERY_SOLVE_ITERATIONS, tolerance=0,
                                     acceleration=acceleration).vertices
                arap_energy(V, F, U, energy=energy)
                cell_distortion(V, F, U, energy=energy)
        _picture_solves()

    solves()
    with policy.every_kernel_threaded():
        solves()


def _picture_solves() -> None:
    """Warp a tiny opaque picture with two pins in each of the puppet warp's modes (:data:`arap.puppet.warp.MODES`),
    as :class:`arap.puppet.PuppetWarp` does, and as the studio does (its Distort mode is the hybrid energy's solve
    with λ = 0, :class:`arap.server.solvers.PlaneSolver`)."""
    from arap.puppet.blend import BlendSolver
    from arap.puppet.warp import MODES, PuppetWarp
    from arap.solve.solver import ArapSolver

    picture = np.full((12, 16, 4), 255, dtype=np.uint8)
    pins, targets = [[3.0, 6.0], [12.0, 6.0]], [[3.0, 6.0], [14.0, 8.0]]
    for mode in cast("tuple[Any, ...]", MODES):
        puppet = PuppetWarp(picture, pins, spacing=2.0, mode=mode)
        puppet.deform(targets)
        if mode == "rigid" and isinstance(puppet._solver, ArapSolver):  # (a rigid warp's solver is ARAP's own)
            BlendSolver(puppet._solver, 0.0).solve(puppet.mesh.vertices[puppet.held],
                                                   point_targets=np.asarray(targets), max_iterations=4)
