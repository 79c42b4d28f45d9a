"""The prediction floor: from the network's two heads to lanes on disk.

- `stamlane.predict.postprocess`: DBSCAN on the lane-pixel embeddings, one curve per lane, in original pixels
  (numpy and scikit-learn; validation, streaming and the experiments decode with it too);
- `stamlane.predict.writers`: lanes in the benchmarks' own formats (TuSimple json-lines, CULane text);
- `stamlane.predict.overlay`: the key frame with its lanes drawn;
- `stamlane.predict.prediction_writer`: `LanePredictionWriter`, the Lightning callback of ``stamlane predict``.

Importing this package imports nothing: the decoder and the writers need no Lightning, only the callback does.
"""
