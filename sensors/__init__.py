"""The active acoustic sensor: excitations, features, FEM modal analysis and modal synthesis.

This package imports neither MuJoCo nor PyAudio: simulation (``aas_gym``) and the real rig
(``real``) both build on it.
"""
