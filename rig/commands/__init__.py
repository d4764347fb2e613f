"""Sub-commands of impact-rig, one module each (registered as entry points)."""
