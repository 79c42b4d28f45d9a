"""stamlane: lane mark detection with pre-aligned spatial-temporal attention (Chen & Xiang, Sensors 2022)."""

__version__ = "0.1.0"
