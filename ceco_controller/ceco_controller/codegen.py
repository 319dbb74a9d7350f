"""Compiled NLP functions: C code generated from the CasADi NLP, compiled once into an on-disk cache.

``compile_nlp`` writes the functions IPOPT needs (f, g, grad_f, jac_g, hess_l) as C,
``compile_functions`` any CasADi Functions (the SQP's); both compile with the C compiler into a
shared object named by a hash of the code and return its path (or None, logged, when no
compiler works).
``stdout_silenced`` keeps qpOASES' licence banner out of a node's output.
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import logging
import os

import casadi

from ceco_core.codegen import CompileError, codegen_cache_dir, compile_cached, generate_functions

__all__ = ["compile_nlp", "compile_functions", "nlp_key", "codegen_cache_dir", "stdout_silenced"]

_LOG = logging.getLogger(__name__)


@contextlib.contextmanager
def stdout_silenced():
    """Silence standard output for the block: Python's ``sys.stdout`` and the process's fd 1.

    qpOASES prints its licence banner whenever a solver object is created, whatever
    ``printLevel`` is set; CasADi routes that text to Python's ``sys.stdout`` (and C code may
    write to fd 1 directly). In a node it would interleave with the node's output on every
    controller build. Only solver construction is wrapped, never a solve. fd 1 is process-wide:
    output other threads write to stdout during the construction (a few hundred ms at start-up)
    is lost too; ROS 2 logs go to stderr unless RCUTILS_LOGGING_USE_STDOUT=1.
    """
    with contextlib.redirect_stdout(io.StringIO()):
        try:
            saved = os.dup(1)
        except OSError:  # no usable fd 1 (e.g. closed): the Python-level redirect is all we can do
            saved = None
        if saved is None:
            yield
            return
        try:
            _libc_fflush()  # what C stdio buffered before the block still goes to the real stdout
            with open(os.devnull, "wb") as devnull:
                os.dup2(devnull.fileno(), 1)
                try:
                    yield
                finally:
                    _libc_fflush()  # what C stdio buffered inside the block goes to /dev/null too
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def _libc_fflush() -> None:
    """fflush(NULL): flush every C stdio output stream (no-op where libc cannot be loaded)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # TypeError: no CDLL(None) on Windows
        pass


def nlp_key(nlp: dict) -> bytes:
    """A deterministic fingerprint of an NLP's expressions (CasADi serialisation of (x, p) -> (f, g))."""
    fn = casadi.Function("ceco_nlp_key", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    return fn.serialize().encode()


def compile_nlp(nlp: dict, flags=("-O1",), cache_dir: str | None = None, plugin: str = "ipopt") -> str | None:
    """Generate C for an NLP's functions as IPOPT needs them (f, g, grad_f, jac_g, hess_l) and compile it.

    ``plugin``: the nlpsol plugin whose function set is generated ('ipopt').

    The file name is a hash of the NLP's serialised expressions, the plugin, the flags, the
    compiler and the CasADi version (the generated code is a deterministic function of these), so
    a changed NLP never loads a stale object and a cache hit costs no code generation (2 ms
    instead of 0.1-0.3 s). Concurrent processes do not race: each compiles to its own temporary
    name and renames it into place atomically (``os.replace``). Returns the path, or None (with a
    log warning) when no C compiler is found or anything fails; the caller then uses the
    in-process functions.
    """

    def generate(tmp: str) -> str:
        with stdout_silenced():
            gen = casadi.nlpsol("ceco_nlp", plugin, nlp, {"print_time": False})
        cwd = os.getcwd()
        os.chdir(tmp)  # generate_dependencies writes relative to the working directory
        try:
            gen.generate_dependencies("ceco_nlp.c")
        finally:
            os.chdir(cwd)
        return os.path.join(tmp, "ceco_nlp.c")

    return _compile_cached("ceco_nlp", nlp_key(nlp) + plugin.encode(), generate, flags, cache_dir)


def compile_functions(
    functions, key: bytes, flags=("-O1",), cache_dir: str | None = None, prefix: str = "ceco_sqp"
) -> str | None:
    """Generate C for CasADi Functions and compile it into a cached shared object (as :func:`compile_nlp`).

    ``key``: bytes that determine the functions' code (e.g. :func:`nlp_key` and the source of the
    function that builds them); the cache file is named by its hash. Load a function from the
    returned path with ``casadi.external(function.name(), path)``.
    """
    return _compile_cached(prefix, key, lambda tmp: generate_functions(functions, tmp, prefix), flags, cache_dir)


def _compile_cached(prefix: str, key: bytes, generate, flags, cache_dir: str | None) -> str | None:
    """:func:`ceco_core.codegen.compile_cached` with the NMPC's fall-back: None (logged) when it cannot compile."""
    try:
        res = compile_cached(prefix, key, generate, flags, cache_dir)
    except CompileError as exc:
        _LOG.warning("NMPC codegen failed (%s); using the in-process NLP functions", exc)
        return None
    if res.built:
        _LOG.info("NMPC codegen: compiled %s in %.1f s", res.path, res.seconds)
    return res.path
