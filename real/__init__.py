"""The physical rig: PyAudio play/record with the same observation API as the simulation."""
