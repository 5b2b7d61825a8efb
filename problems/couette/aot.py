"""Ahead-of-time compiled gPCF kernels: the numba engine without numba's start-up.

Loading numba and its on-disk JIT cache costs a process 0.5-1 s before the first residual
(importing numba, initialising LLVM, linking four cached kernels): for the main job that is
more than the compiled kernels save.  ``numba.pycc`` compiles the same four kernels
(:mod:`problems.couette.compiled`: fields, residual, dense Jacobian, dF/dH), with the argument
types the engine passes them, into an ordinary extension module; importing it takes ~10 ms and
does not import numba.  The kernels are the same LLVM code as the JIT ones (bitwise equal
results, tested).

The module is built once per (kernel source, numba, numpy, Python, machine), on the first use
of the numba engine, into ``$CONTIN_AOT_DIR`` (default: the package's ``__pycache__`` when
writable, else ``~/.cache/contin``), written to a temporary directory and renamed into place.
A second process that finds another one building (a lock file younger than
:data:`STALE_LOCK_S`) does not wait: it uses the JIT kernels.  ``CONTIN_AOT=0`` switches the
ahead-of-time path off (JIT only, as before); a build that fails (no C compiler) is logged
once and the JIT kernels serve.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import logging
import os
import platform
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path
from types import ModuleType

log = logging.getLogger("contin")

#: A build lock older than this (seconds) is taken to be left by a killed process.
STALE_LOCK_S = 600.0
#: Kernel names exported by the module, in the order ``compiled._kernels`` returns them.
KERNELS = ("fields", "residual", "jacobian", "residual_dh")


def enabled() -> bool:
    """False when ``CONTIN_AOT=0`` (JIT kernels only)."""
    return os.environ.get("CONTIN_AOT", "1") != "0"


def _version(dist: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return "none"


def module_name() -> str:
    """``gpcf_kernels_<key>``: the key hashes everything the compiled code depends on."""
    source = Path(__file__).with_name("compiled.py").read_bytes()
    key = hashlib.sha256(b"\0".join([
        source, Path(__file__).read_bytes(), _version("numba").encode(), _version("numpy").encode(),
        sys.version.encode(), platform.machine().encode(), platform.system().encode(),
    ])).hexdigest()[:16]
    return f"gpcf_kernels_{key}"


def directory() -> Path:
    """Where the module is stored (``CONTIN_AOT_DIR``, else ``__pycache__``, else ~/.cache)."""
    env = os.environ.get("CONTIN_AOT_DIR")
    if env:
        return Path(env)
    pycache = Path(__file__).parent / "__pycache__"
    try:
        pycache.mkdir(exist_ok=True)
        if os.access(pycache, os.W_OK):
            return pycache
    except OSError:
        pass
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "contin"


def module_path() -> Path | None:
    """The built module's file, or None when it has not been built."""
    name = module_name()
    folder = directory()
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = folder / f"{name}{suffix}"
        if path.is_file():
            return path
    return None


def load() -> ModuleType | None:
    """The ahead-of-time module when it is built and imports, else None (never raises)."""
    if not enabled():
        return None
    path = module_path()
    if path is None:
        return None
    name = path.name.split(".")[0]
    if name in sys.modules:
        return sys.modules[name]
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    except Exception as exc:  # noqa: BLE001 -- a broken build must fall back to the JIT kernels
        log.info("ahead-of-time gPCF kernels at %s do not load (%s): using the JIT kernels", path, exc)
        return None
    sys.modules[name] = mod
    return mod


def build(jit_kernels: tuple, argtypes: tuple) -> Path | None:
    """Compile ``jit_kernels`` (numba dispatchers, in :data:`KERNELS` order) for ``argtypes``
    (one tuple of numba types per kernel) into the module; its path, or None when another
    process holds the build lock or the build fails (then the caller keeps the JIT kernels)."""
    folder = directory()
    name = module_name()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        log.info("cannot create %s for the ahead-of-time kernels (%s)", folder, exc)
        return None
    lock = folder / f"{name}.lock"
    if not _acquire(lock):
        return None
    try:
        with warnings.catch_warnings():
            # pycc is 'pending deprecation' (numba 0.57+) with no replacement yet; the build
            # falls back to the JIT kernels the day it goes, so users need not see the warning
            warnings.simplefilter("ignore")
            from numba.pycc import CC

        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=folder))
        try:
            cc = CC(name)
            cc.output_dir = str(tmp)
            cc.verbose = False
            for export, kernel, types in zip(KERNELS, jit_kernels, argtypes):
                kernel.compile(types)
                cc.export(export, kernel.overloads[types].signature)(kernel.py_func)
            _compile_with_numpy_errors(cc)
            built = next(p for p in tmp.iterdir() if p.name.startswith(name) and p.suffix in (".so", ".pyd"))
            final = folder / built.name
            os.replace(built, final)
            return final
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    except Exception as exc:  # noqa: BLE001 -- no compiler etc.: the JIT kernels serve
        log.info("ahead-of-time build of the gPCF kernels failed (%s): using the JIT kernels", exc)
        return None
    finally:
        lock.unlink(missing_ok=True)


def _acquire(lock: Path) -> bool:
    """Create ``lock`` exclusively; a lock older than STALE_LOCK_S is removed first."""
    try:
        if time.time() - lock.stat().st_mtime > STALE_LOCK_S:
            lock.unlink(missing_ok=True)
    except FileNotFoundError:
        pass
    try:
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    except FileExistsError:
        return False
    except OSError:
        return False
    os.write(fd, str(os.getpid()).encode())
    os.close(fd)
    return True


def _compile_with_numpy_errors(cc) -> None:
    """``cc.compile()`` with numba's error_model="numpy", as the JIT kernels have it (x / 0 gives
    inf or nan, which the callers check, not a ZeroDivisionError): pycc builds its Flags with
    the default "python" model and has no option for it."""
    import numba.pycc.compiler as pycc_compiler

    base = pycc_compiler.Flags

    class NumpyErrorFlags(base):  # type: ignore[misc, valid-type]
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.error_model = "numpy"

    pycc_compiler.Flags = NumpyErrorFlags
    try:
        cc.compile()
    finally:
        pycc_compiler.Flags = base
