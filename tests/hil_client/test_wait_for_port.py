"""``python -m hil_client.wait_for_port`` (docker-compose's wait for the emulator): bad
usage is one line and exit 2, never a traceback."""

from __future__ import annotations

import pytest

from hil_client.wait_for_port import main


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["lab..local", "5020"], "'lab..local' is no host name"),  # a probe: a traceback
        (["127.0.0.1", "70000"], "70000 is not a TCP port"),  # a probe: "not reachable"
        ([".".join(["a" * 63] * 5), "5020"], "319 characters, over 253"),  # sent to DNS
    ],
)
def test_bad_usage_is_one_line_and_exit_2(capsys, argv, message):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err, err
