"""Hydra configs shipped with the RGBench adapter: env/garment_dynamics.yaml, found by RGBench's
Hydra through the search-path plugin in hydra_plugins/garmentdynamics_searchpath."""
