"""The recording's HDF5 layout (docs/recording_layout.md): the one package that writes and reads it.

One module per idea: :mod:`recording.layout` (what a file holds), :mod:`recording.metadata`
(its root attributes), :mod:`recording.writer`, :mod:`recording.reader`,
:mod:`recording.superblock` and :mod:`recording.checksum` (whether a file is whole), and
:mod:`recording.repair`.  The recorder (``rig.recorder``) writes through it; the replay drivers,
the GUI and the analysis loaders read through it.  It imports nothing of the rig, the GUI, the
drivers or the analysis but the analysis's leaf JSON writer.
"""
