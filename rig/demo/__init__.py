"""The end-to-end demonstration: the virtual rig with a hidden physical effect, recorded and
explained by the same drivers, procedures and analysis a real rig uses, into a report folder.

The virtual rig runs over its real protocols (serial DAQ on a pty, amplifier on
Modbus TCP), faster than real time, with one named cause of docs/MODEL.md section 6
switched on that the baseline model lacks.  The demo records a free decay, an
impact decay and a forced amplitude sweep at 10 Hz (up and down); identifies L,
zeta, K and mu0 with intervals; runs the discrepancy analysis on every record
(without being told the cause); judges the regime of every sweep step; and
draws the measured bifurcation diagram against the one simulated with the
identified model.  Only at the end is the hidden cause revealed, next to what
the analysis named.

The stages import only downward: ``settings`` (names, settings, errors) <- ``record``
(the rig side) and ``report`` (the result, its files and summary) <- ``analyse`` (what is
run on which record) <- ``run`` (the stages in order); ``impact-rig demo`` calls ``run``.
"""
