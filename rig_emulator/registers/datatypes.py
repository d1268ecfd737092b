"""The register encodings a map may use: one declaration, read by the schema and the codec.

Adding an encoding (say ``int64``) is one line here: its name and its ``struct`` code.
Integer types are scaled and saturate at their range; float types are IEEE 754; ``bool``
is one bit (coils and discrete inputs).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class DataType:
    """One encoding: ``code`` is its ``struct`` format character ("" for a bit)."""

    name: str
    code: str

    @property
    def is_float(self) -> bool:
        return self.code in ("e", "f", "d")

    @property
    def is_bit(self) -> bool:
        return not self.code

    @property
    def width(self) -> int:
        """Registers per value (a bit counts as one)."""
        return struct.calcsize(">" + self.code) // 2 if self.code else 1

    @property
    def int_range(self) -> tuple[int, int]:
        """(min, max) of an integer type's raw value."""
        bits = 16 * self.width
        if self.code.isupper():  # unsigned struct codes
            return 0, 2**bits - 1
        return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1

    @property
    def invalid_raw(self) -> int | None:
        """An integer type's invalid code, what an instrument serves for no reading: the
        most negative raw value if signed (0x8000, 0x80000000), the largest if unsigned
        (0xFFFF, 0xFFFFFFFF); None for a float (NaN) or a bit."""
        if self.is_float or self.is_bit:
            return None
        lo, hi = self.int_range
        return lo if lo < 0 else hi

    @property
    def relative_precision(self) -> float:
        """Half a unit in the last place of a float type, relative."""
        return {"e": 2.0**-11, "f": 2.0**-24, "d": 2.0**-53}[self.code]


DATATYPES: dict[str, DataType] = {
    t.name: t
    for t in (
        DataType("int16", "h"),
        DataType("uint16", "H"),
        DataType("int32", "i"),
        DataType("uint32", "I"),
        DataType("float32", "f"),
        DataType("float64", "d"),
        DataType("bool", ""),
    )
}
