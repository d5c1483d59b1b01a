"""Edge-cloud serving of cbnet_mmdet detectors, the package of
the ``projects/edge_serving`` project.

Nothing here is registered in MMDet's registries; the plugin never imports
it (``tests/test_layering.py``). It imports the plugin (the predictor's
models, dataset paths, the dark channel prior's estimates of
:mod:`cbnet_mmdet.utils.dark_channel` for the haze score) and
:mod:`cbnet_tools.markdown`.

* :mod:`.codec`: HTTP body -> image (with the 4xx checks), shared by the
  server and its tests;
* :mod:`.predictor`: MMDet's ``DetInferencer`` behind one ``predict`` call;
* :mod:`.server`: the Ray Serve deployment (HTTP API, dynamic batching);
* :mod:`.haze`: per-frame haze estimate (dark channel prior transmission);
* :mod:`.router`: the edge router (local model, offload, fallback);
* :mod:`.offload`: offload rate against AP from two routed runs.

Ray Serve is an optional extra (``pip install .[serve]``); only
:mod:`.server` imports it.
"""
