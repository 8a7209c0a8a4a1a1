"""train.py's Hydra sweepers and launchers (a Hydra plugin: Hydra instantiates only classes under hydra_plugins).

Hydra imports this package when it scans its plugins, after the plugins it extends, so the
``hydra/launcher`` and ``hydra/sweeper`` options registered here replace theirs.
"""
