"""Registers train.py's ``hydra/launcher`` and ``hydra/sweeper`` options over the plugins' own.

A hook, not a search path: Hydra calls every search-path plugin after its plugin scan, and the scan
runs each plugin's own registration in an order that follows ``sys.path``; registering when this
package is imported could be undone by a plugin imported after it.
"""

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin

from hydra_plugins.waterair_sweeps import launchers, search


class TrainOptions(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        launchers.register()
        search.register()
