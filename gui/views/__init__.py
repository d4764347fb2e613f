"""Live views of the rig's data: time traces, spectrum, Poincare section, phase portrait."""
