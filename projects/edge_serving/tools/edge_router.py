# Thresholds of the edge router (projects/edge_serving/tools/route.py
# --router-cfg), read with mmengine's Config; fields of
# cbnet_serving.router.RouterConfig.
router = dict(
    server_url='http://127.0.0.1:8000',
    # offload when the mean dark-channel transmission is below this
    transmission_thr=0.6,
    # offload when the local model's top score is below this
    min_confidence=0.3,
    # seconds to wait for the server before keeping the local result
    timeout_s=5.0,
    haze_max_side=256,
    mode='auto')
