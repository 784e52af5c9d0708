"""Compiled programs kept on disk between processes: a warm start without tracing or compiling.

JAX's persistent compilation cache (``jax_compilation_cache_dir``) skips only XLA's compilation:
every new process still traces and lowers the solve (~2 s for the benchmark slider–crank with
three clearance joints, more than the cached compile saves). ``stored_jit`` keeps the whole
compiled executable instead (``jax.experimental.serialize_executable``), keyed on everything the
program depends on, so a later process with the same call loads it in ~0.3 s.

The key (SHA-256) covers:
- the call's static structure: every argument with its arrays replaced by (shape, dtype, weak
  type), pickled (mechanism topology, laws, solver settings, output grid size, ...);
- jaxclear's own source (a hash of every ``.py`` file of the package: an edited checkout never
  loads a program built from older code);
- the versions of Python, jax, jaxlib, diffrax, equinox, lineax and optimistix; the backend,
  its devices and the host CPU's feature flags; ``XLA_FLAGS``; the x64 setting;
- the devices the call runs on (``_execution_devices``: the ensemble engine's shares of a chunk,
  each on its own device, are one program per device).

JAX's persistent cache may share the folder (``jaxclear run`` sets it so), but never holds the
store's programs: an executable JAX hands back from its cache cannot be serialized again (its
kernels are missing from the copy, which fails when run: "Function ... not found"). The store's
programs therefore have names of their own, are compiled with JAX's cache writes off, and one JAX
still served from its cache is used but not stored.

Only eager calls are served (under a transformation the arguments are tracers and the call is the
ordinary ``eqx.filter_jit``). A program that calls back into Python (a progress bar) cannot be
stored and is compiled as usual. Equinox's runtime checks are traced in NaN mode here
(``EQX_ON_ERROR=nan``: a raising check is a host callback); the only such checks in a solve are
diffrax's on the output times, which ``simulate`` has already checked on the host.
"""

import contextlib
import dataclasses
import functools
import hashlib
import importlib.metadata
import io
import os
import pickle
import platform
import sys
import tempfile
import threading
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.core  # jax.core.Tracer (jax imports it itself; named for type checkers)
import numpy as np

from ._checks import staging
from ._error_mode import error_mode_set

FORMAT = 1
"""Layout of a stored entry; part of the key."""

MAX_BYTES = 2**30
"""Bytes the store keeps: on writing, the least recently used entries beyond this are deleted
(an entry of the benchmark slider–crank's solve is ~3 MB; each edit of jaxclear's source or
upgrade makes new ones)."""

_folder: list[Path] = []  # the enabled folder, if any (a list: module state without `global`)
_counts = {"loaded": 0, "stored": 0, "compiled": 0, "not_storable": 0}
_instances: "weakref.WeakSet[StoredJit]" = weakref.WeakSet()

_PACKAGES = ("jax", "jaxlib", "diffrax", "equinox", "lineax", "optimistix")


def enable_compilation_cache(folder: "str | os.PathLike[str]") -> Path:
    """Keep compiled simulations in ``folder`` and load them in later processes.

    Eager calls of ``simulate`` and ``assemble`` (and what calls them: ``jaxclear run`` turns this
    on by default) then look for their compiled program in ``folder`` before tracing: a warm
    start of the default run takes ~0.3 s instead of ~2 s with JAX's own persistent cache or
    ~5 s cold. Calls under ``jax.jit``, ``jax.grad``, ``jax.vmap`` ... are unaffected. Entries
    are keyed on the call's static structure, jaxclear's source and the installed versions, so
    a stale entry is never used; delete the folder to reclaim its space.

    Calling it again (with any folder) also drops the programs this process holds in memory, so
    that the next calls read them from the folder.

    Args:
        folder: where compiled programs are written (created if missing).

    Returns:
        The folder, as a ``Path``.

    Raises:
        OSError: the folder cannot be created.
    """
    path = Path(folder).expanduser()
    path.mkdir(parents=True, exist_ok=True)
    _folder[:] = [path]
    for stored in _instances:  # from now on programs come from this folder (or are compiled)
        stored._loaded.clear()
    return path


def disable_compilation_cache() -> None:
    """Stop reading and writing compiled programs (``enable_compilation_cache``)."""
    _folder.clear()


def compilation_cache_folder() -> Path | None:
    """The folder set by ``enable_compilation_cache``, or ``None`` when off."""
    return _folder[0] if _folder else None


def compilation_cache_statistics() -> dict[str, int]:
    """Counts of this process's calls through the store since it started: programs ``loaded``
    from the folder, ``compiled`` (not found), of which ``stored``, and calls ``not_storable``
    (user code in the call, or a program that calls back into Python: compiled as usual)."""
    return dict(_counts)


@functools.cache
def _environment() -> bytes:
    """What a compiled program depends on besides its call: versions, hardware, flags, source."""
    versions = []
    for name in _PACKAGES:
        try:
            versions.append(f"{name}={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            versions.append(f"{name}=?")
    devices = jax.devices()
    parts = [
        f"format={FORMAT}",
        sys.version,
        platform.machine(),
        *versions,
        jax.default_backend(),
        ",".join(f"{d.platform}:{d.device_kind}" for d in devices),
        os.environ.get("XLA_FLAGS", ""),
        str(jax.config.jax_enable_x64),  # pyright: ignore[reportAttributeAccessIssue]
        _cpu_flags(),
        _SOURCE_HASH,
    ]
    return "\n".join(parts).encode()


def _cpu_flags() -> str:
    """The host CPU's feature flags (XLA compiles for them), where the system tells them."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith(("flags", "Features")):
                return line.split(":", 1)[1].strip()
    return platform.processor()


def _source_hash() -> str:
    """SHA-256 of every ``.py`` file of the package, read now."""
    root = Path(__file__).parent.parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


_SOURCE_HASH = _source_hash()
"""The package's source as this process imported it (``import jaxclear`` loads every module),
taken at import rather than at the first stored call, which a long-lived process may make after
its files were edited. (Until 2026-11-28 the hash covered ``jaxclear/_core`` only: edits
elsewhere, e.g. to ``solve/_extremes.py``, kept the key, later processes loaded programs of the
older code, and ``jaxclear run``'s statistics depended on which programs came from the store;
measured: two output grids gave rms_rod_acceleration 17376.81 and 17376.87 m/s², bitwise equal
with an empty store.)"""


_KEYED_PACKAGES = ("jaxclear", *_PACKAGES, "jaxtyping", "numpy", "ml_dtypes")


class _Unkeyed(Exception):
    """The call refers to code whose changes the key would not see."""


class _KeyPickler(pickle.Pickler):
    """Pickles a call for its key; refuses code from outside the keyed packages and the standard
    library (a user's driver function or contact law class: pickled by name only, so an edit to
    it would not change the key)."""

    def reducer_override(self, obj):
        if isinstance(obj, type) or callable(obj) and hasattr(obj, "__module__"):
            module = (getattr(obj, "__module__", None) or "").split(".")[0]
            if module not in _KEYED_PACKAGES and module not in sys.stdlib_module_names:
                raise _Unkeyed(f"{obj!r} from module {module!r}")
            if getattr(obj, "__name__", "") == "<lambda>" or "<locals>" in getattr(
                obj, "__qualname__", ""
            ):
                raise _Unkeyed(f"{obj!r} is not importable")
        return NotImplemented


def _key_bytes(call) -> bytes:
    """The call pickled by value alone. Pickle's memo writes an object met before as a
    back-reference, so two equal calls whose equal strings are or are not one object pickle
    differently: a process that had traced the chunk's solve keyed its statistics program apart
    from one that had loaded it ('driver' shared in one, a copy in the other), and a warm run
    compiled again. Without the memo (``fast``) every object is written out in full."""
    buffer = io.BytesIO()
    pickler = _KeyPickler(buffer, protocol=5)
    pickler.fast = True  # no memo: equal values give equal bytes (a cycle raises: not storable)
    pickler.dump(call)
    return buffer.getvalue()


def _execution_devices(leaves) -> list:
    """The devices the call runs on: those its committed arrays sit on, else the default device.
    A program compiled for one device cannot run on another (the ensemble engine places each
    share of a chunk on its own device), and a loaded program must be told its devices
    (``deserialize_and_load`` assumes all of the backend's: "Expected args ... to have 2
    shards" in a process with two CPU devices)."""
    devices = {
        d.id: d for x in leaves if isinstance(x, jax.Array) and x.committed for d in x.devices()
    }
    if not devices:
        default = jax.config.jax_default_device  # pyright: ignore[reportAttributeAccessIssue]
        device = default if isinstance(default, jax.Device) else jax.devices()[0]
        devices = {device.id: device}
    return [devices[i] for i in sorted(devices)]


class _Slot:
    """Stands for the i-th array of a program's flat output in a stored output skeleton."""

    def __init__(self, index: int):
        self.index = index


@dataclasses.dataclass(frozen=True)
class _Aval:
    """Stands for an argument array in a call's key: what its compiled program depends on."""

    shape: tuple[int, ...]
    dtype: str
    weak_type: bool


def _describe(x) -> _Aval:
    return _Aval(tuple(x.shape), str(x.dtype), bool(getattr(x, "weak_type", False)))


class _Building:
    """The process-wide settings a program is built for the store under, shared by the threads
    that build at once (the ensemble engine builds each device's share from its own thread):
    equinox's checks traced in NaN mode, JAX's persistent cache writing nothing, and a listener
    recording its hits. The first thread in sets them, the last one out restores them (a
    per-thread save and restore would leave them set for good when the builds overlap). A hit
    recorded while several build counts for all of them: such a build is used, not stored."""

    def __init__(self):
        self._lock = threading.Lock()
        self._depth = 0
        self._mode: Any = None  # the error-mode context entered by the first thread in
        self._saved: Any = None  # JAX's persistent-cache threshold before it
        self.hits: list[str] = []

    def _listener(self, event, **kwargs):
        if event == "/jax/compilation_cache/cache_hits":
            self.hits.append(event)

    def _enter(self) -> int:
        with self._lock:
            if self._depth == 0:
                self.hits = []
                self._mode = error_mode_set("nan")
                self._mode.__enter__()
                self._saved = jax.config.jax_persistent_cache_min_compile_time_secs  # pyright: ignore[reportAttributeAccessIssue]
                jax.config.update("jax_persistent_cache_min_compile_time_secs", float("inf"))
                jax.monitoring.register_event_listener(self._listener)
            self._depth += 1
            return len(self.hits)

    def _exit(self) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                jax.monitoring.unregister_event_listener(self._listener)
                jax.config.update("jax_persistent_cache_min_compile_time_secs", self._saved)
                self._mode.__exit__(None, None, None)

    @contextlib.contextmanager
    def __call__(self):
        """Within: build for the store; yields a function telling whether JAX's cache served a
        program since entering."""
        before = self._enter()
        try:
            yield lambda: len(self.hits) > before
        finally:
            self._exit()


_building = _Building()


class _Entry(NamedTuple):
    compiled: Any  # jax.stages.Compiled, called with the flat list of the call's arrays
    skeleton: Any  # the output with _Slot(i) for its i-th array


class StoredJit:
    """``eqx.filter_jit(fun)`` whose eager calls use the executable store when it is enabled."""

    def __init__(self, fun: Callable):
        self._fun = fun
        self._jitted = eqx.filter_jit(fun)
        self._loaded: dict[str, _Entry] = {}
        functools.update_wrapper(self, fun)
        _instances.add(self)

    def __call__(self, *args):
        folder = compilation_cache_folder()
        if folder is None or staging():
            return self._jitted(*args)
        dynamic, static = eqx.partition(args, eqx.is_array)
        leaves, in_def = jax.tree_util.tree_flatten(dynamic)
        if any(isinstance(x, jax.core.Tracer) for x in leaves):
            return self._jitted(*args)
        try:
            described = jax.tree_util.tree_unflatten(in_def, [_describe(x) for x in leaves])
            call = _key_bytes(eqx.combine(described, static))
        except Exception:  # code outside the key, or cannot be pickled: compile as usual
            _counts["not_storable"] += 1
            return self._jitted(*args)
        devices = _execution_devices(leaves)
        placement = ("devices=" + ",".join(str(d.id) for d in devices)).encode()
        key = hashlib.sha256(
            _environment() + self._fun.__qualname__.encode() + call + placement
        ).hexdigest()
        entry = self._loaded.get(key)
        if entry is None:
            entry = self._load(folder, key, devices)
            if entry is not None:
                try:  # wait for the first run: a program that cannot run here fails in it
                    out = jax.block_until_ready(entry.compiled(leaves))
                except jax.errors.JaxRuntimeError:  # loads but cannot run here: compile it again
                    entry = None
                else:
                    self._loaded[key] = entry
                    return self._unflatten(entry, out)
            entry = self._build(folder, key, in_def, static, leaves)
            self._loaded[key] = entry
        return self._unflatten(entry, entry.compiled(leaves))

    @staticmethod
    def _unflatten(entry: _Entry, out):
        return jax.tree_util.tree_map(
            lambda s: out[s.index] if isinstance(s, _Slot) else s,
            entry.skeleton,
            is_leaf=lambda s: isinstance(s, _Slot),
        )

    def _path(self, folder: Path, key: str) -> Path:
        return folder / f"{self._fun.__name__.strip('_')}-{key[:40]}.jaxclear"

    def _load(self, folder: Path, key: str, devices: list) -> "_Entry | None":
        from jax.experimental import serialize_executable

        path = self._path(folder, key)
        if not path.exists():
            return None
        _initialize_lapack()
        try:
            payload, in_tree, out_tree, skeleton = pickle.loads(path.read_bytes())
            compiled = serialize_executable.deserialize_and_load(
                payload, in_tree, out_tree, execution_devices=devices
            )
        except Exception:  # unreadable or from an incompatible build: compile it again
            return None
        with contextlib.suppress(OSError):
            os.utime(path)  # recently used: kept longest by _evict
        _counts["loaded"] += 1
        return _Entry(compiled, skeleton)

    def _build(self, folder: Path, key: str, in_def, static, leaves) -> _Entry:
        from jax.experimental import serialize_executable

        skeletons = []

        def flat(leaves):
            out = self._jitted(*eqx.combine(jax.tree_util.tree_unflatten(in_def, leaves), static))
            dynamic, out_static = eqx.partition(out, eqx.is_array)
            flat_out, out_def = jax.tree_util.tree_flatten(dynamic)
            slots = jax.tree_util.tree_unflatten(out_def, [_Slot(i) for i in range(len(flat_out))])
            skeletons.append(eqx.combine(slots, out_static, is_leaf=lambda s: isinstance(s, _Slot)))
            return flat_out

        # A program JAX's persistent cache hands back cannot be serialized again (its kernels are
        # missing from the copy: "Function ... not found" when the copy runs). So the store's
        # programs have names of their own (their own keys in JAX's cache), JAX does not write
        # them to its cache, and a program JAX still served from its cache is not stored.
        flat.__name__ = f"{self._fun.__name__.strip('_')}_stored_{key[:16]}"
        with _building() as served_from_cache:
            lowered = jax.jit(flat).lower(leaves)
            compiled = lowered.compile()
            hit = served_from_cache()
        _counts["compiled"] += 1
        if hit:
            _counts["not_storable"] += 1
            return _Entry(compiled, skeletons[0])
        entry = _Entry(compiled, skeletons[0])
        if "callback" in lowered.as_text():  # calls back into Python: cannot be stored
            _counts["not_storable"] += 1
            return entry
        try:
            payload, in_tree, out_tree = serialize_executable.serialize(compiled)
            data = pickle.dumps((payload, in_tree, out_tree, entry.skeleton), protocol=5)
        except Exception:
            _counts["not_storable"] += 1
            return entry
        if _write(self._path(folder, key), data):
            _counts["stored"] += 1
            _evict(folder, MAX_BYTES)
        return entry


def _write(path: Path, data: bytes) -> bool:
    """Write atomically (concurrent processes never read half an entry); a full or read-only disk
    costs only the warm start. Returns whether the entry was written."""
    try:
        with tempfile.NamedTemporaryFile(dir=path.parent, delete=False, suffix=".tmp") as f:
            f.write(data)
        os.replace(f.name, path)
        return True
    except OSError:
        with contextlib.suppress(OSError, NameError):
            os.unlink(f.name)  # pyright: ignore[reportPossiblyUnboundVariable]
        return False


def _evict(folder: Path, max_bytes: int) -> None:
    """Delete the least recently used entries until the store holds at most ``max_bytes``."""
    with contextlib.suppress(OSError):
        entries = sorted(
            ((p.stat().st_mtime, p.stat().st_size, p) for p in folder.glob("*.jaxclear")),
            reverse=True,
        )
        total = 0
        for _, size, path in entries:
            total += size
            if total > max_bytes:
                path.unlink(missing_ok=True)


def stored_jit(fun: Callable) -> StoredJit:
    """Decorator: ``eqx.filter_jit`` plus the on-disk store of ``enable_compilation_cache``."""
    return StoredJit(fun)


@functools.cache
def _initialize_lapack() -> None:
    """Load LAPACK's kernels into XLA, as lowering a linear solve does on CPU: a loaded program
    that never went through lowering in this process would otherwise call null kernels (a
    segmentation fault; jax's own ``jax.export`` does the same before calling an exported program).
    """
    jax.jit(jax.numpy.linalg.solve).lower(np.eye(2), np.ones(2))  # NumPy: no eager ops
