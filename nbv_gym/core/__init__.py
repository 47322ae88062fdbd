"""Foundations every layer may use: errors, array aliases and checked array files, grids, poses,
typed configs, tasks, what one robot owns, provenance, output paths, point-cloud files and worker
processes. Nothing here imports another subpackage of nbv-gym."""
