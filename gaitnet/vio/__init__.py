"""Visual-inertial filter and smoother after D.-C. Dang's thesis, chapter 3 (``gaitnet vio``).

The estimator core: :mod:`~gaitnet.vio.state` (the state container),
:mod:`~gaitnet.vio.covariance` (the only code that changes the covariance: propagate, update,
clone, augment, marginalise), :mod:`~gaitnet.vio.imu_propagation` (time update) and one module
per measurement (:mod:`~gaitnet.vio.vo_model`, :mod:`~gaitnet.vio.tag_model`,
:mod:`~gaitnet.vio.foot_model`). Submodules are not imported here; import what you use.
``docs/vio.md`` maps each thesis equation to its function.
"""
