"""Host names the resolver can be asked for (``serve --host``, ``run --rig``,
``wait_for_port``)."""

from __future__ import annotations

import pytest

from rig_emulator.names import HOST_NAME_MAX, host_name_problem

LONGEST = ".".join(["a" * 63, "b" * 63, "c" * 63, "d" * 61])  # 253 characters


@pytest.mark.parametrize(
    "host",
    ["127.0.0.1", "::1", "fe80::1%lo", "localhost", "localhost.", "bücher.example",
     "xn--bcher-kva.example", LONGEST, LONGEST + "."],
)  # fmt: skip
def test_host_names_the_resolver_takes(host):
    assert len(LONGEST) == HOST_NAME_MAX
    assert host_name_problem(host) is None


@pytest.mark.parametrize(
    ("host", "problem"),
    [
        ("lab..local", "a label between dots is empty"),
        ("a" * 64 + ".lab", "over 63 characters"),
        (LONGEST + "e", "254 characters, over 253"),
        # 245 characters, but 6 labels of 'xn--' and 40 encoded letters: 281 (a re-probe)
        (".".join(["ü" * 40] * 6), "in IDNA, over 253"),
        # a label of two characters, refused for mixing directions, not for its length (it
        # was told as "empty or over 63 characters": a re-probe)
        ("a\u05d0.local", "not a name IDNA can encode: Violation of BIDI requirement"),
        ("\udcff.lab", "not a name IDNA can encode: Invalid character"),
    ],
)
def test_host_names_it_does_not(host, problem):
    assert problem in (host_name_problem(host) or "")
