"""nriqa: no-reference quality assessment of Monte Carlo renders (Whittle 2018, ch. 4-5)."""

__version__ = "0.1.0"
