"""Compiled CasADi NLP solvers: a per-machine cache of gcc-built C code, per-process JIT, or no compilation.

CasADi's virtual machine is ≈ 6× slower per IPOPT iteration than compiled C (DESIGN.md §4b), so the NLP
functions are generated as C and compiled with gcc.  ``cache`` mode builds one shared library per
(code identity, Hessian mode, gcc flags, machine) and keeps it under :func:`cache_dir`; ``jit`` compiles in
every process (into a private temp dir, never the working tree); ``none`` interprets.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

from amorgs.solvers.fingerprint import cpu_model


def cache_dir() -> Path:
    """Where compiled NLP libraries are kept: ``$AMORGS_CACHE_DIR`` or ``~/.cache/amorgs``."""
    return Path(os.environ.get("AMORGS_CACHE_DIR", Path.home() / ".cache" / "amorgs"))


def compiled_library_path(name: str, nlp: dict, hessian: str, identity: dict, flags: str,
                          sources: tuple[Path, ...] = ()) -> Path:
    """Where the compile cache keeps the library of ``nlp`` (see :func:`compiled_nlp_library`).

    ``identity`` names what the problem compiles into the code (for the CR3BP: transcription options and the
    boundary states, embedded as constants); the key adds a SHA-256 of the NLP's own expression graph (CasADi's
    serialisation of f and g, ≈ 0.1 s: a change of the code that builds the NLP can never load a stale
    library), the Hessian mode, the CasADi version, the CPU architecture and the gcc flags (plus the CPU model
    and instruction-set flags when they include ``-march=native``), and a SHA-256 of every C source compiled in
    (``sources``: the external functions the NLP calls).
    """
    graph = ca.Function("graph", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]]).serialize()
    key = json.dumps(
        {
            **identity,
            "graph": hashlib.sha256(graph.encode()).hexdigest(),
            "hessian": hessian,
            "casadi": ca.__version__,
            "machine": platform.machine(),
            "flags": flags,
            "cpu": cpu_model() if "native" in flags else "",
            "sources": [hashlib.sha256(Path(src).read_bytes()).hexdigest() for src in sources],
            "format": 1,
        },
        sort_keys=True,
    )
    return cache_dir() / f"{name}_nlp_{hashlib.sha256(key.encode()).hexdigest()[:16]}.so"


def compiled_nlp_library(name: str, nlp: dict, hessian: str, identity: dict, flags: str,
                         sources: tuple[Path, ...] = ()) -> Path:
    """Shared library with the functions IPOPT needs for ``nlp``, generated and compiled once per machine
    (cache key: :func:`compiled_library_path`), with the C ``sources`` of the external functions the NLP calls
    compiled in.  Concurrent workers may race to build it; each compiles into a private temp file and
    ``os.replace`` makes the winner atomic.
    """
    target = compiled_library_path(name, nlp, hessian, identity, flags, sources)
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    plain = ca.nlpsol(name, "ipopt", nlp, {"ipopt": {"hessian_approximation": hessian}})
    with tempfile.TemporaryDirectory(prefix="amorgs-codegen-", dir=target.parent) as tmp:
        cwd = os.getcwd()
        try:
            os.chdir(tmp)
            plain.generate_dependencies(f"{name}_nlp.c")
        finally:
            os.chdir(cwd)
        built = Path(tmp) / target.name
        subprocess.run(
            ["gcc", *flags.split(), "-fPIC", "-shared", str(Path(tmp) / f"{name}_nlp.c"), *map(str, sources),
             "-o", str(built), "-lm"],
            check=True,
            capture_output=True,
        )
        os.replace(built, target)
    return target


def ipopt_nlpsol(
    name: str, nlp: dict, opts: dict, mode: str, flags: str, hessian: str, identity: dict,
    sources: tuple[Path, ...] = (),
) -> tuple[ca.Function, tempfile.TemporaryDirectory | None]:
    """An IPOPT ``nlpsol`` for ``nlp`` with CasADi options ``opts``, compiled per ``mode``.

    ``mode``: ``"cache"`` (:func:`compiled_nlp_library`), ``"jit"`` (compiled in this process; the returned
    temp dir holds the build and must live as long as the solver) or ``"none"``.  ``sources``: the C files of
    the external functions that ``nlp`` calls, compiled into the NLP's code (``cache``, ``jit``); CasADi's
    virtual machine (``none``) calls them in their own libraries.
    """
    if mode == "cache":
        library = compiled_nlp_library(name, nlp, hessian, identity, flags, sources)
        return ca.nlpsol(name, "ipopt", str(library), opts), None
    if mode == "jit":
        # CasADi writes the JIT source into the working directory: build inside a private temp dir.
        jit_dir = tempfile.TemporaryDirectory(prefix="amorgs-jit-")
        opts = {**opts, "jit": True, "jit_cleanup": False, "compiler": "shell",
                "jit_options": {"flags": flags.split(), "verbose": False, "directory": jit_dir.name,
                                # the link step compiles the external functions' sources in, with the same flags
                                "linker_flags": [*flags.split(), "-fPIC", *map(str, sources)]}}
        cwd = os.getcwd()
        try:
            os.chdir(jit_dir.name)
            return ca.nlpsol(name, "ipopt", nlp, opts), jit_dir
        finally:
            os.chdir(cwd)
    if mode == "none":
        return ca.nlpsol(name, "ipopt", nlp, opts), None
    raise ValueError(f"compile mode must be 'cache', 'jit' or 'none', got {mode!r}")
