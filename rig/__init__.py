"""Acquisition engine, HDF5 recorder, procedures, rig configuration and the command line."""
