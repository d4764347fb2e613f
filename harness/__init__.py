"""What the tests and the benchmarks both run on: the DAQ firmware built for the host, the
soak of a lab PC's recording, the fuzzers' strategies and checks, the virtual rig's decays
with a hidden cause, and the benchmarks' figures as data (their results files and the
page made of them).

Unlike :mod:`reference`, this may use the project's model and virtual rig; runtime code
never imports it.
"""
