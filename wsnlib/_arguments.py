"""Number arguments of the package's command lines (argparse types), one message for each kind of mistake."""

from __future__ import annotations

import argparse
import math


def whole_number(lowest: int, highest: int | None = None):
    """An argparse ``type``: a whole number ≥ ``lowest`` (and ≤ ``highest``); anything else is a usage
    error naming the argument and the range."""
    allowed = f">= {lowest}" if highest is None else f"{lowest}-{highest}"

    def whole(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: needs a whole number {allowed}") from None
        if value < lowest or (highest is not None and value > highest):
            raise argparse.ArgumentTypeError(f"{text!r}: needs a whole number {allowed}")
        return value

    return whole


def positive_number(text: str) -> float:
    """An argparse ``type``: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"{text!r}: needs a number > 0")
    return value
