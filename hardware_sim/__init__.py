"""The virtual rig: model physics behind emulators speaking the real wire protocols."""
