"""The benchmark world specs (TOML), shipped as package data of nbv-gym."""
