"""An independent YOLOX in Megvii's own layout and naming (the
``state_dict`` keys of the official ``yolox_nano.pth``: ``backbone.
backbone.dark2.0.dconv.conv.weight``, ``head.stems.0.bn.running_var``...),
written from the published architecture for the converter's tests: its
``forward`` runs the convolutions in YOLOX's order (a ``CSPLayer``'s
``conv1`` before ``conv2``, the head's class branch before its box
branch), so that its ONNX export has the graph of Megvii's, and it
returns what that graph returns (``[B, points, 4 + 1 + classes]``: raw
box offsets, sigmoid objectness and class scores)."""
import torch
from torch import nn


class BaseConv(nn.Module):
    """Convolution (no bias), batch norm, SiLU."""

    def __init__(self, cin, cout, k, stride, groups=1):
        super().__init__()
        self.conv = nn.Conv2d(cin, cout, k, stride, (k - 1) // 2,
                              groups=groups, bias=False)
        self.bn = nn.BatchNorm2d(cout, eps=1e-3, momentum=0.03)
        self.act = nn.SiLU()

    def forward(self, x):
        return self.act(self.bn(self.conv(x)))


class DWConv(nn.Module):
    """Depthwise then pointwise ``BaseConv``."""

    def __init__(self, cin, cout, k, stride):
        super().__init__()
        self.dconv = BaseConv(cin, cin, k, stride, groups=cin)
        self.pconv = BaseConv(cin, cout, 1, 1)

    def forward(self, x):
        return self.pconv(self.dconv(x))


def conv(cin, cout, k, stride, depthwise):
    return DWConv(cin, cout, k, stride) if depthwise else \
        BaseConv(cin, cout, k, stride)


class Bottleneck(nn.Module):

    def __init__(self, cin, cout, shortcut, depthwise):
        super().__init__()
        self.conv1 = BaseConv(cin, cout, 1, 1)
        self.conv2 = conv(cout, cout, 3, 1, depthwise)
        self.use_add = shortcut and cin == cout

    def forward(self, x):
        y = self.conv2(self.conv1(x))
        return x + y if self.use_add else y


class CSPLayer(nn.Module):

    def __init__(self, cin, cout, n, shortcut, depthwise):
        super().__init__()
        hidden = int(cout * 0.5)
        self.conv1 = BaseConv(cin, hidden, 1, 1)
        self.conv2 = BaseConv(cin, hidden, 1, 1)
        self.conv3 = BaseConv(2 * hidden, cout, 1, 1)
        self.m = nn.Sequential(*[
            Bottleneck(hidden, hidden, shortcut, depthwise)
            for _ in range(n)])

    def forward(self, x):
        x_1 = self.conv1(x)  # YOLOX's order: the main branch first
        x_2 = self.conv2(x)
        return self.conv3(torch.cat((self.m(x_1), x_2), 1))


class SPPBottleneck(nn.Module):

    def __init__(self, cin, cout, kernels=(5, 9, 13)):
        super().__init__()
        hidden = cin // 2
        self.conv1 = BaseConv(cin, hidden, 1, 1)
        self.m = nn.ModuleList(
            [nn.MaxPool2d(k, 1, k // 2) for k in kernels])
        self.conv2 = BaseConv(hidden * (len(kernels) + 1), cout, 1, 1)

    def forward(self, x):
        x = self.conv1(x)
        return self.conv2(torch.cat([x] + [m(x) for m in self.m], 1))


class Focus(nn.Module):
    """Space to depth (top-left, bottom-left, top-right, bottom-right),
    then a ``BaseConv``."""

    def __init__(self, cin, cout, k=3):
        super().__init__()
        self.conv = BaseConv(cin * 4, cout, k, 1)

    def forward(self, x):
        return self.conv(torch.cat(
            (x[..., ::2, ::2], x[..., 1::2, ::2], x[..., ::2, 1::2],
             x[..., 1::2, 1::2]), 1))


class CSPDarknet(nn.Module):

    def __init__(self, dep, wid, depthwise):
        super().__init__()
        c, d = int(wid * 64), max(round(dep * 3), 1)
        self.stem = Focus(3, c, 3)
        self.dark2 = nn.Sequential(conv(c, 2 * c, 3, 2, depthwise),
                                   CSPLayer(2 * c, 2 * c, d, True, depthwise))
        self.dark3 = nn.Sequential(
            conv(2 * c, 4 * c, 3, 2, depthwise),
            CSPLayer(4 * c, 4 * c, 3 * d, True, depthwise))
        self.dark4 = nn.Sequential(
            conv(4 * c, 8 * c, 3, 2, depthwise),
            CSPLayer(8 * c, 8 * c, 3 * d, True, depthwise))
        self.dark5 = nn.Sequential(
            conv(8 * c, 16 * c, 3, 2, depthwise),
            SPPBottleneck(16 * c, 16 * c),
            CSPLayer(16 * c, 16 * c, d, False, depthwise))

    def forward(self, x):
        x3 = self.dark3(self.dark2(self.stem(x)))
        x4 = self.dark4(x3)
        return x3, x4, self.dark5(x4)


class YOLOPAFPN(nn.Module):

    def __init__(self, dep, wid, depthwise, in_channels=(256, 512, 1024)):
        super().__init__()
        c0, c1, c2 = (int(c * wid) for c in in_channels)
        n = round(3 * dep)
        self.backbone = CSPDarknet(dep, wid, depthwise)
        self.upsample = nn.Upsample(scale_factor=2, mode='nearest')
        self.lateral_conv0 = BaseConv(c2, c1, 1, 1)
        self.C3_p4 = CSPLayer(2 * c1, c1, n, False, depthwise)
        self.reduce_conv1 = BaseConv(c1, c0, 1, 1)
        self.C3_p3 = CSPLayer(2 * c0, c0, n, False, depthwise)
        self.bu_conv2 = conv(c0, c0, 3, 2, depthwise)
        self.C3_n3 = CSPLayer(2 * c0, c1, n, False, depthwise)
        self.bu_conv1 = conv(c1, c1, 3, 2, depthwise)
        self.C3_n4 = CSPLayer(2 * c1, c2, n, False, depthwise)

    def forward(self, x):
        x2, x1, x0 = self.backbone(x)
        fpn_out0 = self.lateral_conv0(x0)
        f_out0 = self.C3_p4(torch.cat([self.upsample(fpn_out0), x1], 1))
        fpn_out1 = self.reduce_conv1(f_out0)
        pan_out2 = self.C3_p3(torch.cat([self.upsample(fpn_out1), x2], 1))
        pan_out1 = self.C3_n3(
            torch.cat([self.bu_conv2(pan_out2), fpn_out1], 1))
        pan_out0 = self.C3_n4(
            torch.cat([self.bu_conv1(pan_out1), fpn_out0], 1))
        return pan_out2, pan_out1, pan_out0


class YOLOXHead(nn.Module):

    def __init__(self, num_classes, wid, depthwise,
                 in_channels=(256, 512, 1024)):
        super().__init__()
        c = int(256 * wid)
        self.stems, self.cls_convs, self.reg_convs = (nn.ModuleList()
                                                      for _ in range(3))
        self.cls_preds, self.reg_preds, self.obj_preds = (nn.ModuleList()
                                                          for _ in range(3))
        for cin in in_channels:
            self.stems.append(BaseConv(int(cin * wid), c, 1, 1))
            for convs in (self.cls_convs, self.reg_convs):
                convs.append(nn.Sequential(conv(c, c, 3, 1, depthwise),
                                           conv(c, c, 3, 1, depthwise)))
            self.cls_preds.append(nn.Conv2d(c, num_classes, 1))
            self.reg_preds.append(nn.Conv2d(c, 4, 1))
            self.obj_preds.append(nn.Conv2d(c, 1, 1))

    def forward(self, feats):
        outputs = []
        for k, x in enumerate(feats):
            x = self.stems[k](x)
            cls_out = self.cls_preds[k](self.cls_convs[k](x))
            reg_feat = self.reg_convs[k](x)
            out = torch.cat([self.reg_preds[k](reg_feat),
                             self.obj_preds[k](reg_feat).sigmoid(),
                             cls_out.sigmoid()], 1)
            outputs.append(out.flatten(2))
        return torch.cat(outputs, 2).permute(0, 2, 1)


class YOLOX(nn.Module):
    """YOLOX (Nano by default: depth 0.33, width 0.25, depthwise)."""

    def __init__(self, num_classes=80, dep=0.33, wid=0.25, depthwise=True):
        super().__init__()
        self.backbone = YOLOPAFPN(dep, wid, depthwise)
        self.head = YOLOXHead(num_classes, wid, depthwise)

    def forward(self, x):
        return self.head(self.backbone(x))


def random_yolox(seed=0, **kwargs):
    """A seeded YOLOX with random weights and batch-norm statistics, in
    eval mode."""
    torch.manual_seed(seed)
    model = YOLOX(**kwargs)
    for module in model.modules():
        if isinstance(module, nn.BatchNorm2d):
            n = module.num_features
            module.weight.data.uniform_(0.5, 1.5)
            module.bias.data.normal_(0, 0.2)
            module.running_mean.normal_(0, 0.2)
            module.running_var.uniform_(0.5, 2.0)
            module.num_batches_tracked.fill_(7)
            assert n > 0
        elif isinstance(module, nn.Conv2d) and module.bias is not None:
            module.bias.data.normal_(0, 0.5)
    return model.eval()
