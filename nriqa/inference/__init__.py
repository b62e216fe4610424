"""Inference: the Scorer and the shipped weights with their model cards."""

# The shipped single-image weights a user gets without naming any: ``Scorer.from_pretrained()``,
# ``nriqa-predict`` without ``--model``, the render-loop benchmarks. How it was chosen: its card.
DEFAULT_WEIGHTS = "unet_fast"
