"""learning layer: Gumbel-sigmoid, RelationalDeepSym and the DeepSym baselines (and a
symbol-free continuous reference), training, effect-error evaluation and symbol read-out.
Works on arrays only: no Drake here.
"""

from drake_symplan.learning.checkpoint import load_run
from drake_symplan.learning.models import (
    MODELS,
    AttentiveDeepSym,
    ContinuousReference,
    DeepSym,
    EffectModel,
    RelationalDeepSym,
    build_model,
)
from drake_symplan.learning.readout import read_symbols, readout_dataset

__all__ = [
    "MODELS", "AttentiveDeepSym", "ContinuousReference", "DeepSym", "EffectModel",
    "RelationalDeepSym",
    "build_model", "load_run", "read_symbols", "readout_dataset",
]
