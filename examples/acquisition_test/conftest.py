"""Only for running this example inside the project's own checkout: where the package is
installed (``pip install boiler-rig-emulator``), its ``pytest11`` entry point already gives
every suite the ``rig_emulator`` fixture and marker, and a user's suite needs no conftest."""

from rig_emulator.pytest_plugin import rig_emulator  # noqa: F401 - the plugin's fixture


def pytest_configure(config):
    if not config.pluginmanager.has_plugin("rig_emulator.pytest_plugin"):
        from rig_emulator.pytest_plugin import pytest_configure as register_marker

        register_marker(config)
