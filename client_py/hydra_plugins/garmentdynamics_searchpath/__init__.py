"""Hydra search-path plugin of the garmentdynamics package: adds the configs shipped with the
RGBench adapter (pkg://rgbench_garmentdynamics.configs) to every Hydra app's search path, so RGBench
resolves `env=garment_dynamics` without a copy of the file in its own configs/. Hydra discovers it
in the `hydra_plugins` namespace package; it does nothing to apps that never ask for the file."""

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin


class GarmentDynamicsSearchPathPlugin(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        search_path.append(provider="garmentdynamics", path="pkg://rgbench_garmentdynamics.configs")
