"""Only for running this example inside the project's own checkout: where the package is
installed (``pip install boiler-rig-emulator``), its ``pytest11`` entry point already gives
every suite the ``rig_emulator`` fixture and marker, and a user's suite needs no conftest."""

from rig_emulator.pytest_plugin import rig_emulator  # noqa: F401 - the plugin's fixture


def pytest_configure(config):
    if not config.pluginmanager.has_plugin("rig_emulator.pytest_plugin"):
        from rig_emulator.pytest_plugin import pytest_configure as register_marker

        register_marker(config)


def pytest_collection_modifyitems(config, items):
    """Communication faults act through the server's gates (rig_emulator.modbus.handler);
    where a checkout lacks them, say so instead of failing."""
    import pytest

    from rig_emulator.modbus import handler

    if hasattr(handler, "GateDecision"):
        return
    skip = pytest.mark.skip(reason="this checkout's Modbus server has no gates (GateDecision)")
    for item in items:
        if any(k in item.name for k in ("no_reply", "delay", "exception", "disconnect")):
            item.add_marker(skip)
