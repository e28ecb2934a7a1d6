"""A CasADi function as C, compiled once with the system's C compiler and called in place.

CasADi generates C for any :class:`~casadi.Function` (``CodeGenerator``); compiled with
``gcc -O2`` into a shared library it runs without CasADi's virtual machine, and called
through :mod:`ctypes` on numpy buffers that stay bound to it, a call costs a few
microseconds instead of the tens that converting numpy arrays to CasADi matrices takes on
every call of ``function(...)``. Inputs may be any float64 C-contiguous arrays whose memory
outlives the binding, MuJoCo's ``MjData`` arrays included (their memory is fixed for the
life of the ``MjData``), so a physics step passes MuJoCo's state with no copy at all.

The library is cached under ``$XDG_CACHE_HOME/cosim`` (``~/.cache/cosim``), in a folder named
by a hash of the generated source, so a given function is compiled once per machine (about a
second). The cache is not trusted: every entry is written under a temporary name and renamed
into place whole, and its library's size and SHA-256 are checked before each load (a
truncated library mapped into the process would end it with SIGBUS; another library under
the name would lack the function). A damaged entry is rebuilt once, an unwritable cache
is worked around for the run, each with a one-line warning
(:func:`compiled_library`). :func:`compile_function` returns None when no C compiler works,
and the caller keeps its plain implementation.
"""

from __future__ import annotations

import atexit
import ctypes
import functools
import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from cosim.core.built_on_disk import kept_before, kept_on_disk
from cosim.core.compiled_cache import (
    build_lock,
    cache_dir,
    entry_damage,
    install,
    mark_used,
    private_folder,
    prune,
    remove,
)

COMPILER_FLAGS = ("-O2",)
"""Optimisation flags (:data:`ALWAYS_FLAGS` are always added)."""

ALWAYS_FLAGS = ("-fno-math-errno", "-ffp-contract=off", "-shared", "-fPIC")
"""Flags of every library. ``-fno-math-errno``: the math functions need not set ``errno``,
so gcc computes ``sqrt`` with one instruction instead of a call guarded for negative
arguments, and may treat ``sin``, ``exp`` ... as pure functions of their arguments: the same
correctly rounded results (no reassociation, no contraction: IEEE arithmetic is untouched),
so a run's every number is the same as without it, and the generated code is faster.
``-ffp-contract=off``: no ``a * b + c`` fused into one instruction (where the processor has
FMA, :data:`NATIVE_FLAGS`), whose single rounding would change the numbers."""

NATIVE_FLAGS = ("-march=native",)
"""Flags for the processor of the machine that builds: the compiler uses its vector
instructions (AVX, AVX-512 ...) on the long straight-line code CasADi generates, so the
filter's models, its joint update and the NLP's functions run faster, with the same
numbers (each operation still rounded alone: :data:`ALWAYS_FLAGS`). A
library so built runs only on a processor like it: the cache key holds the processor
(:func:`host_processor`), so machines sharing a cache (a home folder on the network) each
build their own. A compiler that does not take the flags builds without them
(:func:`native_flags`)."""


class CompiledFunction:
    """One compiled CasADi function bound to its input and output buffers.

    ``inputs`` and ``outputs`` are float64, C-contiguous numpy arrays holding each
    argument densely (sizes checked against the function); :meth:`__call__` evaluates the
    function from the inputs' current contents into the outputs.
    """

    def __init__(self, library: ctypes.CDLL, function: ca.Function,
                 inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]) -> None:
        for kind, arrays, count, size in (
            ("input", inputs, function.n_in(), function.nnz_in),
            ("output", outputs, function.n_out(), function.nnz_out),
        ):
            if len(arrays) != count:
                raise ValueError(f"{function.name()}: {len(arrays)} {kind}s, expected {count}")
            for i, array in enumerate(arrays):
                if (array.dtype != np.float64 or not array.flags.c_contiguous
                        or array.size != size(i)):
                    raise ValueError(f"{function.name()}: {kind} {i} must be a C-contiguous "
                                     f"float64 array of {size(i)} numbers")
        self._keep = (tuple(inputs), tuple(outputs))  # the buffers outlive the pointers
        self._entry = getattr(library, function.name())
        self._entry.restype = ctypes.c_int
        self._library = library
        pointer = ctypes.c_void_p
        self._arg = (pointer * max(function.sz_arg(), 1))(*[a.ctypes.data for a in inputs])
        self._res = (pointer * max(function.sz_res(), 1))(*[a.ctypes.data for a in outputs])
        self._iw = (ctypes.c_longlong * max(function.sz_iw(), 1))()
        self._w = (ctypes.c_double * max(function.sz_w(), 1))()
        self._name = function.name()

    def __call__(self) -> None:
        if self.status_of_call():
            raise RuntimeError(f"{self._name}: the compiled function reported an error")

    def status_of_call(self) -> int:
        """Evaluate, and return the function's status (0: success) instead of raising:
        for a function whose failure is a result (one holding a QP solver reports an
        unsolved QP this way)."""
        return int(self._entry(self._arg, self._res, self._iw, self._w, 0))


class CompiledCacheWarning(UserWarning):
    """The cache of compiled libraries is damaged or cannot be written (the run goes on)."""


def _private_entry(entry: Path) -> Path:
    """Where this process keeps ``entry``'s library when the cache cannot take it: a folder
    of the process's own (:func:`private_folder`), so that a second user of the same library
    in the process loads it instead of building it again."""
    where = hashlib.sha256(os.fsencode(entry)).hexdigest()[:16]  # the cache's folder too
    return private_folder() / where


def _private_copy(built: Path, entry: Path) -> Path:
    """``built`` copied to :func:`_private_entry`."""
    folder = _private_entry(entry)
    if not folder.parent.exists():
        atexit.register(shutil.rmtree, folder.parent, ignore_errors=True)
    folder.mkdir(parents=True, exist_ok=True)
    return Path(shutil.copy2(built, folder / built.name))


COMPILE_TIMEOUT_S = 900.0
"""A compiler that takes longer than this on one library is stopped (a build of the largest
NLP takes about a minute on a loaded 2-core machine)."""


class CompileFailedWarning(CompiledCacheWarning):
    """A library could not be built: the run goes on without it, slower (one line with the
    compiler's first error)."""


def compiler() -> list[str] | None:
    """The C compiler's command: ``$CC`` (with its arguments, e.g. ``gcc -m64``) or ``gcc``;
    None when it is not found."""
    command = shlex.split(os.environ.get("CC") or "gcc")
    if not command or shutil.which(command[0]) is None:
        return None
    return [shutil.which(command[0]) or command[0], *command[1:]]


@functools.lru_cache(maxsize=1)
def host_processor() -> str:
    """This machine's processor as :data:`NATIVE_FLAGS` see it, for the cache key: the
    vendor, model and instruction-set flags the kernel reports for the first processor
    (``/proc/cpuinfo``; on ARM its features, implementer and part), else the platform's
    machine and processor names."""
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as info:
            for line in info:
                if not line.strip() and fields:
                    break  # the first processor's block ends
                name, _, value = line.partition(":")
                fields.setdefault(name.strip(), value.strip())
    except OSError:
        pass
    found = [fields.get(name, "") for name in (
        "vendor_id", "model name", "flags", "CPU implementer", "CPU part", "Features")]
    if any(found):
        return " | ".join(found)
    import platform  # only here: a millisecond of every process start otherwise

    uname = platform.uname()
    return f"{uname.machine} {uname.processor}"


@functools.lru_cache(maxsize=4)
def native_flags(command: tuple[str, ...]) -> tuple[str, ...]:
    """:data:`NATIVE_FLAGS` if the compiler ``command`` takes them (it preprocesses an
    empty file with them: a few milliseconds, once per process that builds), else none."""
    try:
        subprocess.run([*command, *NATIVE_FLAGS, "-E", "-x", "c", os.devnull], check=True,
                       capture_output=True, timeout=60)
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired, OSError):
        return ()
    return NATIVE_FLAGS


def _first_error(stderr: str) -> str:
    """The compiler's first error line (else its first line), without the file's folder."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    chosen = next((line for line in lines if "error" in line.lower()), lines[0] if lines
                  else "no message")
    return chosen if len(chosen) <= 300 else chosen[:297] + "..."


def _build(command: Sequence[str], flags: Sequence[str], source: Path, name: str,
           extra_sources: Sequence[Path] = (), link_flags: Sequence[str] = (),
           fallback: str = "") -> Path | None:
    """Compile ``source`` (and ``extra_sources``) into a library beside it; None, with a
    :class:`CompileFailedWarning` naming the compiler's first error, when it fails."""
    library = source.with_name(f"{name}.so")
    try:
        subprocess.run([*command, *flags, "-o", str(library), str(source),
                        *map(str, extra_sources), "-lm", *link_flags],
                       check=True, capture_output=True, text=True, errors="replace",
                       timeout=COMPILE_TIMEOUT_S)
    except subprocess.CalledProcessError as error:
        why = _first_error(error.stderr or "")
    except subprocess.TimeoutExpired:
        why = f"stopped after {COMPILE_TIMEOUT_S:g} s"
    except OSError as error:
        why = error.strerror or str(error)
    else:
        return library
    warnings.warn(f"cannot compile {name} ({command[0]}: {why}): "
                  f"{fallback or 'the run goes on without it, slower'}", CompileFailedWarning,
                  stacklevel=3)
    return None


Functions = Sequence[ca.Function] | Callable[[], Sequence[ca.Function]]
"""CasADi functions, or a callable that makes them (called only when they must be built)."""


def compiled_library(name: str, functions: Functions,
                     flags: Sequence[str] = COMPILER_FLAGS,
                     note: str | None = None, key: str | Callable[[], str] | None = None,
                     extra_sources: Sequence[Path] = (),
                     link_flags: Sequence[str] = (),
                     edit_source: Callable[[str], str] | None = None,
                     fallback: str = "", relocatable: Sequence[Path] = (),
                     recipe: str | None = None) -> Path | None:
    """The shared library holding ``functions`` (each under its own name), compiled with
    ``flags`` or found in the cache; None when no C compiler is available or compiling
    fails. ``name`` names the file (a C identifier). ``note``, if given, is printed as one
    line on stderr (``cosim: note: ...``) when the library is compiled rather than found,
    for a build that makes the user wait.

    The cache entry is keyed by a hash of the generated source and the flags, and holds
    the library with its size and SHA-256, checked before it is used: a damaged entry (a
    truncated file, another library under the name) is rebuilt once, with a one-line
    :class:`CompiledCacheWarning`. When the cache cannot be written the library is compiled
    into a folder of this process's own, with a one-line warning, and the run goes on.

    Generating the source costs about 0.1 s for a large NLP; a caller that can name the
    functions more cheaply passes ``key`` (a string that determines them, e.g. a
    serialised CasADi function they are all derived from) and ``functions`` as a callable
    producing them: the entry is then keyed by ``key``, the flags and CasADi's version, and
    the functions are generated only when the entry must be built. ``key`` may be a callable
    making the string, and ``recipe`` what the functions are built from (the ``repr`` of the
    builders' arguments, in the project's own code): the entry's hash is then kept on disk
    for the recipe (:func:`cosim.core.built_on_disk.kept_on_disk`), so a new process with the
    same recipe and code finds the entry without making the key (serialising the EKF's
    functions and hashing their 8 MB took 70 ms of every process's set-up).

    ``extra_sources`` (C files of one's own, e.g. calling the generated functions) are
    compiled into the same library and ``link_flags`` passed last; both are part of the
    entry's hash. ``edit_source`` rewrites the generated C before it is compiled (to work
    around a fault of CasADi's code generator); with ``key``, the key must name the edit.
    A build that fails says so in one :class:`CompileFailedWarning` with the compiler's first
    error and ``fallback`` (what the run does instead); no compiler at all is the caller's to
    say (:func:`compiler` is None).

    ``relocatable`` names folders of dependencies (a Python package's shared libraries and
    headers) whose place differs between virtualenvs holding the same version: their paths
    in the flags are left out of the entry's hash (:func:`relocated`), so every virtualenv
    with that version finds one entry, a fresh clone's too; the key must name the version.
    The library's run path still names the folder it was built against, so the caller loads
    the dependency from its own folder before the library (``import mujoco`` loads
    libmujoco; :func:`tracker.mpc.compiled_rti.load_hpipm`): the dynamic loader then takes
    the loaded one by its soname, even where the run path's folder is gone.
    """
    command = compiler()
    if command is None:
        return None
    flags = (*flags, *ALWAYS_FLAGS)
    own = b"".join(Path(extra).read_bytes() for extra in extra_sources)
    hashed_flags = _hashed_flags(flags, link_flags, relocatable)
    entry = None
    if key is not None:  # found without generating anything, nor a temporary folder
        digest = _entry_digest(name, key, own, hashed_flags, recipe)
        entry = cache_dir() / f"{name}-{digest[:16]}"
        found = _cached(entry, name)
        if found is not None:
            return found
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp, f"{name}.c")
        if entry is None:
            _generate(name, functions, tmp, edit_source)
            digest = _source_digest(source.read_bytes() + own, hashed_flags)
            entry = cache_dir() / f"{name}-{digest[:16]}"
            found = _cached(entry, name)
            if found is not None:
                return found
        private = _private_entry(entry) / f"{name}.so"
        if private.is_file():  # built by this process for an unwritable cache
            return private
        # One process builds an entry; another that needs it meanwhile (a sweep's workers on
        # an empty cache) waits, then loads it instead of building it too.
        with build_lock(entry):
            found = _cached(entry, name)
            if found is not None:
                return found
            if key is not None:
                _generate(name, functions, tmp, edit_source)
            if note is not None:
                kept = (f"once per machine, cached in {entry.parent}" if _writable(entry.parent)
                        else f"for this run only: the cache {str(entry.parent)!r} cannot be "
                        "written")
                print(f"cosim: note: {note} ({kept})", file=sys.stderr, flush=True)
            built = _build(command, (*flags, *native_flags(tuple(command))), source, name,
                           extra_sources, link_flags, fallback)
            if built is None:
                return None
            try:
                installed = install(built, entry, f"{name}.so")
                prune(keep=entry)  # the cache stays within its bound (compiled_cache)
                return installed
            except OSError as error:
                _say_unwritable(str(entry.parent), str(error.strerror or error))
                return _private_copy(built, entry)


@functools.cache
def _say_unwritable(folder: str, reason: str) -> None:
    """Warn that the cache ``folder`` cannot be written, once per process for each folder
    and reason: a run builds several libraries, and the warnings filter's own "once per
    place" forgets what it said whenever a ``warnings.catch_warnings`` block ends (before:
    a run with an unwritable cache said the same line three times)."""
    warnings.warn(f"cannot write the compiled-code cache {folder!r} ({reason}): compiling "
                  "for this run only (XDG_CACHE_HOME names the cache)", CompiledCacheWarning,
                  stacklevel=1)


def _writable(folder: Path) -> bool:
    """Whether ``folder`` (made if missing) can take a new entry."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK)


def _hashed_flags(flags: Sequence[str], link_flags: Sequence[str],
                  relocatable: Sequence[Path]) -> tuple[str, ...]:
    """What of the build the entry's hash holds besides the source: the compiler flags
    (the processor's own included: :data:`NATIVE_FLAGS`, :func:`host_processor`) and the
    link flags, the ``relocatable`` folders' paths replaced (:func:`relocated`)."""
    return relocated((*flags, *NATIVE_FLAGS, *link_flags, f"processor: {host_processor()}"),
                     relocatable)


def relocated(flags: Sequence[str], folders: Sequence[Path]) -> tuple[str, ...]:
    """``flags`` with the path of each of ``folders`` replaced by a placeholder naming its
    position (:func:`compiled_library`'s ``relocatable``)."""
    flags = tuple(flags)
    for i, folder in enumerate(folders):
        flags = tuple(flag.replace(str(folder), f"<dependency {i}>") for flag in flags)
    return flags


def _cached(entry: Path, name: str) -> Path | None:
    """The library of an intact cache entry (marked used); None when there is none, or it
    was damaged (removed, with a warning, to be rebuilt)."""
    if not entry.is_dir():
        return None
    damage = entry_damage(entry, f"{name}.so")
    if not damage:
        mark_used(entry)
        return entry / f"{name}.so"
    warnings.warn(f"the compiled library {str(entry)!r} is damaged ({damage}): "
                  "rebuilding it", CompiledCacheWarning, stacklevel=3)
    remove(entry)
    return None


def _generate(name: str, functions: Functions, folder: str,
              edit_source: Callable[[str], str] | None = None) -> None:
    """Write the C source of ``functions`` (or of what the callable returns) as
    ``folder/name.c``, rewritten by ``edit_source`` if given."""
    generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    for function in functions() if callable(functions) else functions:
        generator.add(subexpressions_shared(function))
    generator.generate(f"{folder}/")
    if edit_source is not None:
        source = Path(folder, f"{name}.c")
        source.write_text(edit_source(source.read_text()))


def subexpressions_shared(function: ca.Function) -> ca.Function:
    """``function`` with each repeated subexpression computed once, when it is a flat
    expression graph (``SXFunction``; any other is returned as it is).

    CasADi builds a graph by operations, so an expression formed twice (the same ``cos``
    of a stage's heading in its dynamics and its cost, the same products in the Hessian of
    every stage's Lagrangian) is two nodes, and its generated C computes it twice.
    Common subexpression elimination (CasADi's ``cse``) merges nodes that apply the same
    operation to the same nodes: every operation left is one the graph held, on the same
    operands, so each output is the same number, bit for bit; there are fewer of them
    (a fifth fewer in the NMPC's Hessian of the Lagrangian), and less code to fetch on
    every call. The function keeps its name, inputs and outputs, so a solver that loads
    it by name (fatrop) finds it.

    A function whose graph shares them already (built with ``{"cse": True}``) is returned
    itself, not a copy: a function that another one calls (the filter's sub-step, which
    its covariance step calls) is then generated once, where the copy and the original
    were two functions to CasADi's generator, each with its own C."""
    if not function.is_a("SXFunction"):
        return function
    inputs = function.sx_in()
    shared = ca.Function(function.name(), inputs, function.call(inputs), function.name_in(),
                         function.name_out(), {"cse": True})
    return shared if shared.n_instructions() < function.n_instructions() else function


GENERATION = "cse"
"""How the C of a library is generated beyond CasADi's own code generator
(:func:`subexpressions_shared`): part of every keyed entry's hash, so an entry built
before it is not taken for one built with it."""


def _source_digest(content: bytes, flags: Sequence[str]) -> str:
    """The hash naming a cache entry: of what determines the source, and the flags."""
    return hashlib.sha256(content + " ".join(flags).encode()).hexdigest()


def _entry_digest(name: str, key: str | Callable[[], str], own: bytes,
                  flags: tuple[str, ...], recipe: str | None) -> str:
    """:func:`_keyed_digest` of ``key`` (made by calling it, if a callable), or, with a
    ``recipe``, the one an earlier process found for the same recipe, flags, own sources,
    CasADi and code (:mod:`cosim.core.built_on_disk`)."""
    def made() -> str:
        return _keyed_digest(key() if callable(key) else key, own, flags)

    if recipe is None:
        return made()
    return str(kept_on_disk(f"{name}_key", _recipe_arguments(recipe, own, flags), made,
                            valid=_is_digest))


def _recipe_arguments(recipe: str, own: bytes, flags: tuple[str, ...]) -> str:
    """What names the entry's hash kept for a ``recipe``: the recipe, CasADi's version, the
    flags and the caller's own sources."""
    return (f"{recipe}\ncasadi {ca.__version__}\n{flags!r}\n"
            f"{hashlib.sha256(own).hexdigest()}")


@functools.lru_cache(maxsize=64)
def external_function(name: str, library: Path) -> ca.Function:
    """The compiled function ``name`` of ``library`` as a CasADi function
    (``casadi.external``), once per process for a library and name: every user shares it,
    as they would share the function built once (:mod:`cosim.core.built_once`)."""
    return ca.external(name, str(library))


def recorded_library(name: str, recipe: str,
                     flags: Sequence[str] = COMPILER_FLAGS) -> Path | None:
    """The library :func:`load_library` with this ``recipe`` (and no sources of the
    caller's own) would load, when an earlier process built or found it and kept its entry's
    hash for the recipe, the entry intact; None otherwise, and without a C compiler (with
    none, no library is loaded). Nothing is built or generated: a caller that gets a path
    may take its functions from it (``casadi.external``) instead of building their graphs,
    then load it as before, by the same recipe."""
    if compiler() is None:
        return None
    hashed_flags = _hashed_flags((*flags, *ALWAYS_FLAGS), (), ())
    kept = kept_before(f"{name}_key", _recipe_arguments(recipe, b"", hashed_flags),
                       valid=_is_digest)
    if kept is None:
        return None
    entry = cache_dir() / f"{name}-{str(kept[0])[:16]}"
    if not entry.is_dir() or entry_damage(entry, f"{name}.so"):
        return None
    return entry / f"{name}.so"


def _is_digest(value: object) -> bool:
    """Whether ``value`` is a SHA-256 in hex, as :func:`_keyed_digest` gives."""
    return (isinstance(value, str) and len(value) == 64
            and all(c in "0123456789abcdef" for c in value))


@functools.lru_cache(maxsize=8)
def _keyed_digest(key: str, own: bytes, flags: tuple[str, ...]) -> str:
    """:func:`_source_digest` of a ``key`` (with CasADi's version and the caller's own
    sources), once per process for an equal key: a key of serialised functions runs to
    megabytes for an NLP, and hashing it again cost every run's set-up some milliseconds.
    Eight kept (about a process's libraries), so the memory held stays bounded."""
    return _source_digest(f"{key}\ncasadi {ca.__version__}\n{GENERATION}".encode() + own,
                          flags)


@functools.lru_cache(maxsize=16)
def _functions_key(functions: tuple[ca.Function, ...]) -> str:
    """The functions serialised and joined, the key of their library: one string object
    per tuple of functions (CasADi functions are immutable), whose hash Python keeps."""
    return "\n".join(serialized(function) for function in functions)


def compile_function(function: ca.Function, fallback: str = "") -> ctypes.CDLL | None:
    """The shared library of ``function`` (compiled or from the cache), or None when no C
    compiler is available or compiling fails (:func:`load_library` of one function)."""
    return load_library(function.name(), [function], fallback=fallback)


def function_by_recipe(name: str, graph: Callable[[], ca.Function], recipe: str,
                       fallback: str = "") -> tuple[ctypes.CDLL, ca.Function] | None:
    """The library of the one function ``name`` that ``graph()`` builds (compiled or from
    the cache, as :func:`compile_function`), loaded, and the function to bind it with: when
    an earlier process kept the library for ``recipe`` (what the graph is built from, see
    :func:`compiled_library`) the function is taken from the library
    (:func:`external_function`) and the graph is never built; otherwise it is built, and
    the library found by the graph's serialisation and kept for the recipe. None as
    :func:`load_library`."""
    found = recorded_library(name, recipe)
    function = graph() if found is None else external_function(name, found)
    library = compiled_library(name, lambda: [graph()], key=lambda: serialized(graph()),
                               fallback=fallback, recipe=recipe)
    loaded = None if library is None else _loaded(library, [name], fallback)
    return None if loaded is None else (loaded, function)


@functools.lru_cache(maxsize=64)
def serialized(function: ca.Function) -> str:
    """``function.serialize()``, once per function object (a CasADi function is immutable
    and hashed by identity): a model built once per process is hashed once, not at every
    run's set-up (the EKF's nine functions, some 40 ms)."""
    return function.serialize()


def load_library(name: str, functions: Sequence[ca.Function],
                 note: str | None = None, fallback: str = "",
                 flags: Sequence[str] = COMPILER_FLAGS,
                 recipe: str | None = None) -> ctypes.CDLL | None:
    """The shared library ``name`` holding ``functions``, compiled (with ``note``, see
    :func:`compiled_library`) or from the cache, and loaded; None when no C compiler is
    available, compiling fails or the library cannot be loaded (with a warning).

    The cache entry is found by a hash of the serialised functions, so their C is
    generated only to build it; with a ``recipe`` (what the functions are built from, see
    :func:`compiled_library`) a new process need not serialise them."""
    library = compiled_library(name, functions, flags=flags, note=note,
                               key=lambda: _functions_key(tuple(functions)),
                               fallback=fallback, recipe=recipe)
    return None if library is None else \
        _loaded(library, [function.name() for function in functions], fallback)


def _loaded(library: Path, names: Sequence[str], fallback: str) -> ctypes.CDLL | None:
    """``library`` loaded, each of ``names`` in it; None, with a warning, when it does not
    load (and its cache entry removed, never kept for the next run to trip on)."""
    try:
        loaded = ctypes.CDLL(str(library))
        for name in names:
            getattr(loaded, name)
    except (OSError, AttributeError) as error:  # checked, so only a changing file gets here
        if library.parent.parent == cache_dir():
            remove(library.parent)
        warnings.warn(f"cannot load the compiled library {str(library)!r} ({error}): "
                      f"{fallback or 'using the plain implementation'}",
                      CompileFailedWarning, stacklevel=4)
        return None
    return loaded
