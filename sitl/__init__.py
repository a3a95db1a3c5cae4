"""A simulated MAVLink multicopter (PX4-like) for flying missions without hardware: see
``sitl/README.md``."""
