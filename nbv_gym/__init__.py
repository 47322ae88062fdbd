"""nbv-gym: a benchmark for autonomous lidar exploration and Next-Best-View research."""

from __future__ import annotations

__version__ = "0.1.0"
