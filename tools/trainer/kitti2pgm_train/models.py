"""SqueezeSeg and PointSeg, with LiDAR-only, early-fusion and mid-fusion inputs.

SqueezeSeg (Wu et al. 2018): conv1 (3x3, stride 1x2) and a 1x1 skip on the input, max pools that
halve the width only, fire modules fire2..fire9, then fireDeconv modules fire10..fire13 that
double the width back, each added to the encoder feature of the same size, dropout, a 3x3
classifier, and optionally the recurrent CRF (``crf.py``). PointSeg (Wang et al. 2018) keeps that
skeleton and adds squeeze reweighting (channel attention) after each fire stage and an
enlargement layer (atrous spatial pyramid pooling) after fire9.

Inputs (``INPUTS``): ``xyzdi`` (x, y, z, intensity, range: the LiDAR baseline), ``xyzdirgb``
(early fusion: the 8 channels stacked) and ``xyzdi+dirgb`` (mid fusion: a LiDAR encoder over x, y,
z, intensity, range and a second encoder over range, intensity, r, g, b; their fire9 features are
concatenated and reduced by a 1x1 convolution before the decoder, and their skip features are
added, as the paper's best variant).
"""

from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

import torch
import torch.nn as nn
import torch.nn.functional as F

from .names import INPUTS, MODELS  # noqa: F401 (re-exported)


def conv(cin: int, cout: int, k, stride=1, padding=0, dilation=1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, k, stride, padding, dilation=dilation), nn.ReLU(inplace=True))


class Fire(nn.Module):
    """SqueezeNet fire: 1x1 squeeze, then 1x1 and 3x3 expands concatenated."""

    def __init__(self, cin: int, squeeze: int, e1: int, e3: int):
        super().__init__()
        self.squeeze = conv(cin, squeeze, 1)
        self.e1 = conv(squeeze, e1, 1)
        self.e3 = conv(squeeze, e3, 3, padding=1)

    def forward(self, x):
        s = self.squeeze(x)
        return torch.cat([self.e1(s), self.e3(s)], 1)


class FireDeconv(nn.Module):
    """fireDeconv: 1x1 squeeze, a 1x4 transposed convolution doubling the width, then expands."""

    def __init__(self, cin: int, squeeze: int, e1: int, e3: int):
        super().__init__()
        self.squeeze = conv(cin, squeeze, 1)
        self.up = nn.Sequential(nn.ConvTranspose2d(squeeze, squeeze, (1, 4), (1, 2), (0, 1)), nn.ReLU(inplace=True))
        self.e1 = conv(squeeze, e1, 1)
        self.e3 = conv(squeeze, e3, 3, padding=1)

    def forward(self, x):
        s = self.up(self.squeeze(x))
        return torch.cat([self.e1(s), self.e3(s)], 1)


class SqueezeReweight(nn.Module):
    """PointSeg's squeeze reweighting: global pooling, bottleneck, sigmoid channel weights."""

    def __init__(self, c: int, reduction: int = 16):
        super().__init__()
        self.fc = nn.Sequential(nn.Conv2d(c, max(c // reduction, 4), 1), nn.ReLU(inplace=True),
                                nn.Conv2d(max(c // reduction, 4), c, 1), nn.Sigmoid())

    def forward(self, x):
        return x * self.fc(F.adaptive_avg_pool2d(x, 1))


class Enlargement(nn.Module):
    """PointSeg's enlargement layer: atrous spatial pyramid pooling (rates 6, 9, 12), a 1x1
    branch and global pooling, concatenated and fused by a 1x1 convolution."""

    def __init__(self, c: int, branch: int):
        super().__init__()
        self.b0 = conv(c, branch, 1)
        self.b = nn.ModuleList([conv(c, branch, 3, padding=r, dilation=r) for r in (6, 9, 12)])
        self.pool = conv(c, branch, 1)
        self.fuse = conv(5 * branch, c, 1)

    def forward(self, x):
        g = self.pool(F.adaptive_avg_pool2d(x, 1)).expand(-1, -1, x.shape[2], x.shape[3])
        return self.fuse(torch.cat([self.b0(x)] + [b(x) for b in self.b] + [g], 1))


def _pool():
    # Halves the width only (ceil mode, as SqueezeSeg's 'SAME' padding).
    return nn.MaxPool2d((3, 3), (1, 2), (1, 1), ceil_mode=False)


class Encoder(nn.Module):
    """conv1 .. fire9; returns fire9 and the skip features (conv1_skip, conv1, fire3, fire5)."""

    def __init__(self, cin: int, w: float, pointseg: bool):
        super().__init__()
        c = lambda n: max(int(round(n * w)), 4)  # noqa: E731 - width multiplier
        self.c = c
        self.conv1 = conv(cin, c(64), 3, (1, 2), 1)
        self.conv1_skip = conv(cin, c(64), 1)
        self.pool1 = _pool()
        self.fire2, self.fire3 = Fire(c(64), c(16), c(64), c(64)), Fire(c(128), c(16), c(64), c(64))
        self.pool3 = _pool()
        self.fire4, self.fire5 = Fire(c(128), c(32), c(128), c(128)), Fire(c(256), c(32), c(128), c(128))
        self.pool5 = _pool()
        self.fire6 = Fire(c(256), c(48), c(192), c(192))
        self.fire7 = Fire(c(384), c(48), c(192), c(192))
        self.fire8 = Fire(c(384), c(64), c(256), c(256))
        self.fire9 = Fire(c(512), c(64), c(256), c(256))
        self.pointseg = pointseg
        if pointseg:
            self.sr3, self.sr5, self.sr9 = SqueezeReweight(c(128)), SqueezeReweight(c(256)), SqueezeReweight(c(512))
            self.enlarge = Enlargement(c(512), c(128))
        self.out_channels = c(512)

    def forward(self, x) -> Tuple[torch.Tensor, List[torch.Tensor]]:
        c1 = self.conv1(x)
        skip0 = self.conv1_skip(x)
        f3 = self.fire3(self.fire2(self.pool1(c1)))
        if self.pointseg:
            f3 = self.sr3(f3)
        f5 = self.fire5(self.fire4(self.pool3(f3)))
        if self.pointseg:
            f5 = self.sr5(f5)
        f9 = self.fire9(self.fire8(self.fire7(self.fire6(self.pool5(f5)))))
        if self.pointseg:
            f9 = self.enlarge(self.sr9(f9))
        return f9, [skip0, c1, f3, f5]


class Decoder(nn.Module):
    """fire10 .. fire13 with skip additions, dropout, the 3x3 classifier."""

    def __init__(self, cin: int, c, dropout: float, num_classes: int):
        super().__init__()
        self.fire10 = FireDeconv(cin, c(64), c(128), c(128))
        self.fire11 = FireDeconv(c(256), c(32), c(64), c(64))
        self.fire12 = FireDeconv(c(128), c(16), c(32), c(32))
        self.fire13 = FireDeconv(c(64), c(16), c(32), c(32))
        self.drop = nn.Dropout2d(dropout)
        self.conv14 = nn.Conv2d(c(64), num_classes, 3, padding=1)

    @staticmethod
    def _fit(x, like):
        # Pooling with odd widths can leave a column more or less: crop or pad to the skip.
        if x.shape[3] != like.shape[3]:
            x = F.pad(x, (0, like.shape[3] - x.shape[3])) if x.shape[3] < like.shape[3] else x[..., :like.shape[3]]
        return x

    def forward(self, f9, skips):
        skip0, c1, f3, f5 = skips
        x = self._fit(self.fire10(f9), f5) + f5
        x = self._fit(self.fire11(x), f3) + f3
        x = self._fit(self.fire12(x), c1) + c1
        x = self._fit(self.fire13(x), skip0) + skip0
        return self.conv14(self.drop(x))


class SegNet(nn.Module):
    """A SqueezeSeg-family network over one input (early fusion) or two (mid fusion)."""

    def __init__(self, model: str, inputs: str, num_classes: int, width_mult: float = 1.0, dropout: float = 0.5,
                 crf: bool = False):
        """``num_classes``: the width of the output, the number of classes of the shards' class map."""
        super().__init__()
        if model not in MODELS:
            raise ValueError(f"unknown model {model!r}; choose from {sorted(MODELS)}")
        if inputs not in INPUTS:
            raise ValueError(f"unknown input {inputs!r}; choose from {sorted(INPUTS)}")
        self.model, self.inputs = model, inputs
        pointseg = model == "pointseg"
        groups = INPUTS[inputs]
        self.encoders = nn.ModuleList([Encoder(len(g), width_mult, pointseg) for g in groups])
        enc: Encoder = self.encoders[0]  # type: ignore[assignment]  # (ModuleList items are Modules)
        cin = enc.out_channels
        self.fuse = None
        if len(groups) == 2:
            self.fuse = conv(2 * cin, cin, 1)
        self.decoder = Decoder(cin, enc.c, dropout, num_classes)
        self.crf = None
        if crf:
            from .crf import RecurrentCRF
            self.crf = RecurrentCRF(num_classes)

    def forward(self, xs: Sequence[torch.Tensor], mask: Optional[torch.Tensor] = None,
                xyz: Optional[torch.Tensor] = None):
        """``xs``: one input tensor per encoder (N x C x H x W). Returns class logits N x K x H x W."""
        outs = [e(x) for e, x in zip(self.encoders, xs)]
        if self.fuse is None:
            f9, skips = outs[0]
        else:
            f9 = self.fuse(torch.cat([outs[0][0], outs[1][0]], 1))
            skips = [a + b for a, b in zip(outs[0][1], outs[1][1])]
        logits = self.decoder(f9, skips)
        if self.crf is not None:
            logits = self.crf(logits, xyz, mask)
        return logits

