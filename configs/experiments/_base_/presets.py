# The data and budgets the experiment sets run under (compare_recipes.py
# --preset NAME; each set file names its default). Every value is one run's
# budget: training iterations of `batch_size` images, a linear warm-up of
# `warmup_iters`, then a poly decay to 0; `img_scale` (w, h) is given to
# every Resize of the training and test pipelines (None: each config's);
# `transfer_root`: the real-fog folder of recipes with a second test set.
presets = dict(
    # the older tables of docs/accuracy.md: 128x256 generated scenes, 120
    # iterations of 4 images (every recipe at 1-5 AP)
    demo=dict(data_root='data/cityscapes_like', iters=120, batch_size=4,
              warmup_iters=30),
    # the benchmark (docs/accuracy.md, "The benchmark"): 600 iterations of 4
    # 256x512 generated scenes, 15 epochs of the 160 training images with
    # instances
    bench=dict(data_root='data/cityscapes_like_bench', iters=600,
               batch_size=4, warmup_iters=30, img_scale=(512, 256)),
    # fine-tuning an ImageNet trunk on real fog: 900 iterations of 2 photos
    # are 12 epochs of DAWN's 152 training photos (fog + haze with at least
    # one object), every photo at most 640x480 (DAWN's 1280-wide ones
    # halved); the configs' lr is set for batches of 2
    realfog_pretrained=dict(data_root='data/dawn_fog', iters=900,
                            batch_size=2, warmup_iters=50,
                            img_scale=(640, 480)),
    # real masks: 36 epochs of the 71 COCO street training photos with
    # street objects, 1290 iterations of 2 (at 12 epochs the stock cascade
    # had not fit its own training photos: docs/accuracy.md)
    coco_street=dict(data_root='data/coco_street', iters=1290, batch_size=2,
                     warmup_iters=50, img_scale=(640, 480)),
    # trained on the clear COCO street photos at the coco_street budget,
    # every run also tested on DAWN's fog + haze val at the same size
    fog_transfer=dict(data_root='data/coco_street', iters=1290,
                      batch_size=2, warmup_iters=50, img_scale=(640, 480),
                      transfer_root='data/dawn_fog'),
    # the bench preset's data and budget, DAWN's val photos resized alike
    fog_generated_to_real=dict(
        data_root='data/cityscapes_like_bench', iters=600, batch_size=4,
        warmup_iters=30, img_scale=(512, 256),
        transfer_root='data/dawn_fog'),
    # a COCO-pretrained detector on real fog: the realfog_pretrained data,
    # size and images seen (1800: 12 epochs of the 152 training photos) in
    # 450 iterations of 4, the batch the YOLOX-Nano configs' lr is set for
    realfog_coco=dict(data_root='data/dawn_fog', iters=450, batch_size=4,
                      warmup_iters=50, img_scale=(640, 480)),
    # the realfog set (from scratch, demo-size models) on DAWN's fog + haze
    # at the budget of its H100 record (docs/robustness/
    # realfog_h100_200it_partial.json): the lent GPU's (its device key)
    realfog_200it=dict(data_root='data/dawn_fog', iters=200, batch_size=4,
                       warmup_iters=10),
)
# Real data: the name the test split of a data folder is reported under
# (the records' condition, which keys their metrics), by the folder's name
# (a data_root's last folder, as device_data below). A recipe whose
# config's data_root is such a folder (wherever --data-root moves it: the
# realfog recipes on RTTS are real fog too) is tested on its own test set
# as it is, with no synthetic fog densities (compare_recipes.py,
# ap_drop.py); any other recipe tests Cityscapes-layout data: clear val,
# then foggy val per beta.
test_conditions = dict(dawn_fog='real fog', coco_street='coco street')
# What the lent GPU machine (tools/device/run_all.py) does with each data
# folder a preset names (its data_root's or transfer_root's last folder,
# the folder of that name under run_all.py --data, data/device/): `make`,
# the command (the project interpreter's arguments; {path} and {nproc}
# filled in) that makes it there instead of carrying it (the generator is
# deterministic); `tiny`, `module:function(root)` writing tiny data of its
# kind for a dry run (none: a dry run needs the folder under --data);
# `dry_img_scale`, the dry run's (w, h); `val_only`, (val_fraction, seed)
# of its seeded split as the configs set them (configs/realfog/_base_/
# voc-fog_box.py): as a transfer_root only its val photos are tested, so
# it travels as `<folder>_val`, every XML and those photos (--prepare
# copies them), which keeps a call under the device tool's 64 MiB.
device_data = dict(
    cityscapes_like=dict(
        make=['tools/misc/generate_cityscapes_like.py', '{path}',
              '--preset', 'demo', '--nproc', '{nproc}', '--convert'],
        tiny='cbnet_tools.synthetic.cityscapes_like:tiny_converted',
        dry_img_scale=(256, 128)),
    cityscapes_like_bench=dict(
        make=['tools/misc/generate_cityscapes_like.py', '{path}',
              '--preset', 'bench', '--nproc', '{nproc}', '--convert'],
        tiny='cbnet_tools.synthetic.cityscapes_like:tiny_converted',
        dry_img_scale=(256, 128)),
    # DAWN's fog + haze photos in the VOC layout (docs/robustness.md)
    dawn_fog=dict(tiny='cbnet_tools.synthetic.voc_folder:tiny_fog_folder',
                  dry_img_scale=(160, 96), val_only=(0.3, 0)),
    # the converted split with the photos copied (a link would travel as a
    # link): tools/dataset_converters/coco_street.py SRC
    # data/device/coco_street --copy
    coco_street=dict(dry_img_scale=(256, 128)),
)
