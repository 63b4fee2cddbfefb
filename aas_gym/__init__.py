"""MuJoCo scenes, contact datastream, simulated acoustic sensor and Gymnasium environments."""
