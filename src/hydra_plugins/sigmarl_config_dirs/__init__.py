"""Hydra finds the users' config folders (`--config-dir`, $SIGMARL_CONFIG_PATH) before the
package's conf/, so a user's `study/paper.yaml` shadows the shipped one, as sigmarl's own
lookups (scenarios, maps) already do. Hydra's `hydra.searchpath` key only appends after the
primary folder, where a file of a shipped name is never reached; a search-path plugin is
Hydra's way to prepend. Hydra discovers it in the `hydra_plugins` namespace package."""

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin

from sigmarl.paths import user_conf_dirs


class SigmarlConfigDirs(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        for folder in reversed(user_conf_dirs()):  # the first folder named ends up first
            search_path.prepend(provider="sigmarl-user", path=f"file://{folder}")
