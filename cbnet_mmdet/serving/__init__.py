"""Edge-cloud serving of cbnet_mmdet detectors (issue 29).

Self-contained: nothing here is registered in MMDet's registries.

* :mod:`.codec`: HTTP body -> image (with the 4xx checks), shared by the
  server and its tests;
* :mod:`.predictor`: MMDet's ``DetInferencer`` behind one ``predict`` call;
* :mod:`.server`: the Ray Serve deployment (HTTP API, dynamic batching);
* :mod:`.haze`: per-frame haze estimate (dark channel prior transmission);
* :mod:`.router`: the edge router (local model, offload, fallback).

Ray Serve is an optional extra (``pip install .[serve]``); only
:mod:`.server` imports it.
"""
