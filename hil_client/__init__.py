"""Lab side of the bench: protocol runner, rig backends, acquisition and analysis.

Layers, imports pointing one way only: ``protocol`` (test methods and runner) <- ``rigs``
(in-process and Modbus backends) <- acquisition (``log``) and analysis; ``cli`` on top.
"""
