"""Evaluation against ground truth: metrics (pure math) and the ``gaitnet evaluate`` job."""
