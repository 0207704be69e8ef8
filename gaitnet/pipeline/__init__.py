"""The end-to-end inference after the thesis (sec. 4.2.4): pose correction of the predictor's
poses towards the filter's pelvis and the segmenter's feet (eq. 4.7, 4.8), and the
camera-to-pelvis extrinsic from the standing frames. Submodules are not imported here; import
what you use (:mod:`~gaitnet.pipeline.pose_correction`, :mod:`~gaitnet.pipeline.pose_types`,
:mod:`~gaitnet.pipeline.pelvis_extrinsic`)."""
