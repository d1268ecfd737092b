"""The request handler's scheduling: requests finish at once, or as a task if they wait."""

from __future__ import annotations

import asyncio

from rig_emulator.modbus.handler import run_now


def test_a_request_that_never_waits_finishes_at_once():
    async def main() -> list[str]:
        done: list[str] = []

        async def inner() -> None:
            done.append("inner")

        async def request() -> None:
            await inner()
            done.append("request")

        run_now(request())
        return done  # no await in between: nothing else ran

    assert asyncio.run(main()) == ["inner", "request"]


def test_a_request_that_waits_is_finished_as_a_task():
    async def main() -> tuple[list[int], list[int]]:
        done: list[int] = []

        async def request() -> None:
            for i in range(3):
                await asyncio.sleep(0.01)
                done.append(i)

        run_now(request())
        early = list(done)
        await asyncio.sleep(0.2)
        return early, done

    early, done = asyncio.run(main())
    assert early == []
    assert done == [0, 1, 2]
