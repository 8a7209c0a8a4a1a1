"""Evaluation of learned policies against the baselines and the upper bound (docs/evaluation.md).

:mod:`.scenarios` (S1-S3), :mod:`.policies` (which files), :mod:`.runner` (rollouts on identical
seas), :mod:`.metrics`, and the outputs: :mod:`.report`, :mod:`.plots`, :mod:`.figures`.
"""
