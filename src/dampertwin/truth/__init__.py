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
  resonance (fixture.py); parts as built (params.py).

It may import the generic solver, the sensors, the excitations and the
design loader (nominal values), never ``dampertwin.model`` (a test walks
the imports; another compares function bodies).
"""

TRUTH_VERSION = "dampertwin-truth 1"
