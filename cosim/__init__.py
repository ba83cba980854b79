"""cosim: a driving simulator with a lockstep VANET layer for assessing cooperative driver assistance."""

__version__ = "0.1.0"
