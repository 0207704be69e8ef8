"""Foot/leg segmentation (thesis sec. 4.1): HHA, the RGB+HHA late-fusion FCN-8s, focal loss,
post-processing to foot keypoints, and ONNX inference."""
