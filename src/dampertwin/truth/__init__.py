"""The virtual laboratory's reference damper ("truth"), written from other,
higher-fidelity physics than the model under calibration (issue 32,
DESIGN.md 9).

The twin (``dampertwin.model``) describes the triple-tube semi-active damper
with the thesis' chapter-4 equations. A real damper is not made of those
equations, so the lab measures this package instead:

- shim stacks from annular-plate bending (plate.py, shims.py), intake valves
  on coil springs with a seat of finite width (intake.py);
- a pilot-operated solenoid valve with its coil, current driver, pilot
  poppet and main stage (solenoid.py): its P/Q map emerges;
- oil with a Murnaghan equation of state, Walther viscosity and thermal
  expansion, entrained gas dissolving at a finite rate (Henry's law), tube
  walls from Lame's thick-cylinder formula (fluid.py, chambers.py);
- a reserve gas with heat exchange and dissolution (gas.py);
- a generalised Maxwell-slip rod seal (seal.py), a generalised Maxwell
  rubber top mount with the Payne effect (mount.py), the test fixture's
  resonance (fixture.py); parts as built (params.py);
- hidden effects, off unless a sample names them under ``truth: effects:``
  (params.OFF_BY_DEFAULT): an eccentric piston band (chambers.py), a
  two-node oil / steel thermal network (thermal.py), top-mount free play
  closed by impact contacts (freeplay.py), air entrained from the reserve at
  low pressure and released at a finite rate (aeration.py). Their states
  run only when one is on (configurations "damper+" / "module+").

The design's ``architecture:`` (params.py, passive.py) builds the thesis'
triple tube, or a passive twin tube (no third tube, no active valve) or
mono tube (no base valves either; a floating piston WITH mass and O-ring
friction between the compression oil and the gas, floating.py: the model's
is massless and frictionless). The parts an architecture lacks are not built
(their parameters NaN). The triple tube's runs are bit for bit those before
the passive architectures (tests/test_truth_passive.py, the lab's data).

It may import the generic solver, the sensors, the excitations and the
design loader (nominal values), never ``dampertwin.model`` (a test walks
the imports; another compares function bodies).
"""

from ..numba_cache import configure as _configure_cache

_configure_cache()  # numba's cache folder before the truth's functions are decorated

TRUTH_VERSION = "dampertwin-truth 3"  # 2: ports before the stacks, swept pilot, walls across chambers, passive Payne;
# 3: the piston band's flow and force in the frame of the bore-sized chambers


def _refresh_compiled_cache() -> None:
    """Numba's on-disk cache of a compiled function is keyed by its own
    file's time stamp, not by the files of the functions it calls (the
    assembled right-hand sides call every submodel): after an edit of a
    submodel the assembly would run stale machine code. A hash of all the
    truth's sources, kept beside the cache, drops the cache when any
    source changed."""
    import hashlib
    from pathlib import Path

    here = Path(__file__).parent
    h = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(here.glob("*.py")))).hexdigest()
    cache = here / "__pycache__"
    stamp = cache / "truth-sources.sha256"
    try:
        if stamp.is_file() and stamp.read_text() == h:
            return
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        tmp = cache / f"truth-sources.{id(h)}.tmp"
        tmp.write_text(h)
        tmp.replace(stamp)
    except OSError:  # a read-only install keeps its cache
        pass


_refresh_compiled_cache()
