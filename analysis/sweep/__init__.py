"""Sweeps as the analysis sees them: a drive stepped up and back down, each step a record.

:mod:`analysis.sweep.steps` holds the value every sweep is turned into (a
:class:`~analysis.sweep.steps.Sweep` of :class:`~analysis.sweep.steps.SweepStep` records,
with the steps set aside and why); the loaders, the shared identification across steps and
the comparison of bifurcation diagrams build on it.
"""
