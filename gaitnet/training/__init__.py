"""Training infrastructure shared by the entry scripts in ``train/`` (shaped after
torchvision's ``references/`` scripts).

* :mod:`~gaitnet.training.distributed`: torchrun environment (``RANK``, ``WORLD_SIZE``,
  ``LOCAL_RANK``), process group (only when ``WORLD_SIZE > 1``; gloo on CPU), reductions;
* :mod:`~gaitnet.training.seeding`: seeding of python, numpy and torch, and the state of every
  generator a run uses (saved in checkpoints, restored on resume);
* :mod:`~gaitnet.training.logs`: a rank-0 logging filter and the run's log setup;
* :mod:`~gaitnet.training.metrics`: ``metrics.csv`` (append-safe on resume, never a NaN) +
  TensorBoard (optional);
* :mod:`~gaitnet.training.checkpoint`: atomic ``last.pt`` / ``best.pt``, loadable with
  ``torch.load(..., weights_only=True)``, git hash;
* :mod:`~gaitnet.training.predictor`: the motion predictor's typed training config and data;
* :mod:`~gaitnet.training.scripts`: the entry scripts' error contract (one line, exit 1).

The scripts stay flat (``train_one_epoch()``, ``evaluate()``, ``main(args)``); what they share
lives here.
"""
