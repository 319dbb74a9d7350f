"""Compiled CasADi Functions: C generated from them, compiled once by the system C compiler into an on-disk cache.

The generic part shared by the NMPC (:mod:`ceco_controller.codegen`) and the plant's compiled fast path
(:mod:`ceco_plant_sim.compiled_plant`). :func:`compile_cached` turns a C file written by a callback into
a shared object ``<cache>/<prefix>_<hash>.so``:

* named by the SHA-256 of a key (the generated code itself, or bytes that determine it), the compiler
  flags, the compiler's resolved path and the CasADi version: a changed code never loads a stale object;
* next to it ``<prefix>_<hash>.so.sha256``, the SHA-256 of the object's bytes: an object that does not
  match it (truncated, overwritten, half-written) is rebuilt, never loaded;
* process- and thread-safe: each builder compiles into its own temporary names and renames them into
  place (``os.replace``, atomic on POSIX); the compile runs in a temporary directory on a relative file
  name, so two builders of one key write the same bytes and a reader never sees a mixture;
* no compiler (``compiler`` / $CC / gcc / cc not executable) or a failed compile raises
  :class:`CompileError`: the caller falls back to its in-process functions and says so.

Load a function from the returned path with ``casadi.external(name, path)``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pathlib
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence

import casadi

__all__ = [
    "CompileError",
    "Compiled",
    "codegen_cache_dir",
    "find_compiler",
    "compile_cached",
    "generate_functions",
    "file_sha256",
    "check_compile_settings",
]


def check_compile_settings(owner: str, compiler, flags, cache_dir, flags_field: str = "flags") -> None:
    """Raise ValueError naming ``owner.<field>`` unless the compile settings of a settings class are usable.

    ``compiler`` and ``cache_dir``: None or a non-empty string; ``flags`` (field ``flags_field``): a tuple of
    strings (the settings of :func:`compile_cached` as the plant's and the oracle's settings carry them).
    """
    if compiler is not None and not (isinstance(compiler, str) and compiler):
        raise ValueError(f"{owner}.compiler: must be a non-empty string or None, got {compiler!r}")
    if not (isinstance(flags, tuple) and all(isinstance(f, str) for f in flags)):
        raise ValueError(f"{owner}.{flags_field}: must be a tuple of strings, got {flags!r}")
    if cache_dir is not None and not (isinstance(cache_dir, str) and cache_dir):
        raise ValueError(f"{owner}.cache_dir: must be a non-empty string or None, got {cache_dir!r}")


class CompileError(RuntimeError):
    """No usable C compiler, or the code did not compile (the message says which and why)."""


@dataclasses.dataclass(frozen=True)
class Compiled:
    """A shared object in the cache."""

    path: str
    """The shared object's path."""
    built: bool
    """True if this call compiled it (False: a cache hit)."""
    seconds: float
    """Wall time of this call [s]: code generation and compilation when built, else the lookup and check."""


def codegen_cache_dir(path: str | None = None) -> pathlib.Path:
    """Directory of compiled objects: ``path``, else $CECO_CACHE_DIR, else $XDG_CACHE_HOME/ceco, else ~/.cache/ceco."""
    if path:
        return pathlib.Path(path)
    if os.environ.get("CECO_CACHE_DIR"):
        return pathlib.Path(os.environ["CECO_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return pathlib.Path(base) / "ceco"


def find_compiler(compiler: str | None = None) -> str | None:
    """The C compiler's resolved path: ``compiler`` (a name on PATH or a path), else $CC, else gcc, else cc.

    None when the one asked for (or, without a request, every candidate) is not an executable.
    """
    for cand in [compiler] if compiler else [os.environ.get("CC"), "gcc", "cc"]:
        if not cand:
            continue
        found = shutil.which(cand)
        if found:
            return os.path.realpath(found)
        if compiler or os.environ.get("CC") == cand:  # an explicit request that does not exist: no silent substitute
            return None
    return None


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def generate_functions(functions: Sequence[casadi.Function], directory: str, name: str) -> str:
    """Write C for ``functions`` into ``directory/name.c`` (one CasADi CodeGenerator); return the file's path."""
    cg = casadi.CodeGenerator(f"{name}.c")
    for f in functions:
        cg.add(f)
    cwd = os.getcwd()
    os.chdir(directory)  # CodeGenerator.generate writes relative to the working directory
    try:
        cg.generate()
    finally:
        os.chdir(cwd)
    return os.path.join(directory, f"{name}.c")


def _valid(target: pathlib.Path) -> bool:
    """The object exists and its bytes have the recorded SHA-256."""
    try:
        want = target.with_name(target.name + ".sha256").read_text().strip()
        return bool(want) and file_sha256(target) == want
    except OSError:
        return False


def compile_cached(
    prefix: str,
    key: bytes | None,
    generate: Callable[[str], str],
    flags: Sequence[str] = ("-O1",),
    cache_dir: str | None = None,
    compiler: str | None = None,
) -> Compiled:
    """``<cache>/<prefix>_<hash>.so``, compiled from the C file ``generate(tmp_dir)`` writes unless a valid one exists.

    Args:
        prefix: file-name prefix (also the C file's name).
        key: bytes that determine the generated code (e.g. a serialised CasADi Function); None: the
            generated C file itself is the key (always generated, 0.1-0.2 s for the plant).
        generate: writes the C file into the directory it is given; returns its path.
        flags: compiler flags (part of the key).
        cache_dir: cache directory (:func:`codegen_cache_dir`).
        compiler: C compiler (:func:`find_compiler`).

    Raises :class:`CompileError` (no compiler, compile failed, cache not writable).
    """
    t0 = time.perf_counter()
    cc = find_compiler(compiler)
    if cc is None:
        raise CompileError(f"no C compiler found ({compiler or os.environ.get('CC') or 'gcc/cc'})")
    cache = codegen_cache_dir(cache_dir)
    meta = repr((list(flags), casadi.CasadiMeta.version(), cc)).encode()
    try:
        with tempfile.TemporaryDirectory(prefix="ceco_cg_") as tmp:
            src = None
            if key is None:
                src = generate(tmp)
                key = pathlib.Path(src).read_bytes()
            digest = hashlib.sha256(key + meta).hexdigest()[:20]
            target = cache / f"{prefix}_{digest}.so"
            if _valid(target):
                return Compiled(str(target), False, time.perf_counter() - t0)
            if src is None:
                src = generate(tmp)
            local = f"{prefix}.c"
            if os.path.basename(src) != local:
                shutil.copyfile(src, os.path.join(tmp, local))
            res = subprocess.run(
                [cc, "-shared", "-fPIC", *flags, local, "-o", "out.so", "-lm"],
                cwd=tmp,
                capture_output=True,
                text=True,
                timeout=1800,
            )
            if res.returncode != 0:
                raise CompileError(f"{cc} failed: {res.stderr.strip()[-500:]}")
            cache.mkdir(parents=True, exist_ok=True)
            sha = file_sha256(os.path.join(tmp, "out.so"))
            part = cache / f".{prefix}_{digest}.{os.getpid()}.{time.monotonic_ns()}.tmp"
            part_so, part_sha = part.with_name(part.name + ".so"), part.with_name(part.name + ".sha256")
            try:
                shutil.copyfile(os.path.join(tmp, "out.so"), part_so)
                part_sha.write_text(sha + "\n")
                # the checksum first: a reader that finds the new object finds its checksum
                os.replace(part_sha, target.with_name(target.name + ".sha256"))
                os.replace(part_so, target)
            finally:
                part_so.unlink(missing_ok=True)
                part_sha.unlink(missing_ok=True)
            return Compiled(str(target), True, time.perf_counter() - t0)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CompileError(f"{type(exc).__name__}: {exc}") from exc
