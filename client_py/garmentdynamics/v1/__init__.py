"""Generated gRPC stubs of garmentdynamics.v1 (written here by setup.py at build time)."""
