"""The independent reference: records drawn from docs/MODEL.md by scipy's DOP853, for the tests
and the benchmarks alike.

:mod:`reference.simulator` integrates the impact pendulum with events and shares no code with
the project's integrator (``analysis.simulate``), its virtual rig (``hardware_sim``) or
:mod:`harness.hidden_cause`; the generators around it draw the cases (decays, forced records,
sweeps, effects outside the named causes) and write them as a lab would, through the
project's file formats.  ``tests/reference/test_no_common_mode.py`` checks that no module
here takes data from the project's model; runtime code never imports this package.
"""
