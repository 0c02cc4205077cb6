"""How the report's Markdown writes its numbers: p-values, signed differences, seed counts."""

from __future__ import annotations

import math

import pandas as pd


def p_text(p: float) -> str:
    """A p-value to three decimals, "<0.001" below that, "–" where there is none."""
    if not math.isfinite(p):
        return "–"
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def signed(x: float, digits: int = 3) -> str:
    """x with its sign, to `digits` decimals ("–" where it is not finite)."""
    return f"{x:+.{digits}f}" if pd.notna(x) and math.isfinite(x) else "–"


def seeds_text(n) -> str:
    """A seed count, "–" where there is none."""
    return "–" if pd.isna(n) else str(int(n))
