"""SqueezeSeg's recurrent CRF: mean-field iterations as a recurrent layer.

Each iteration filters the label probabilities with two kernels over a local 3 x 5 window of the
range image: a bilateral one (Gaussian in the angular position and in the 3D distance between
points) and a spatial one (Gaussian in the angular position), applies a learned compatibility
transform, and subtracts the message from the unary logits. Empty cells (mask 0) send no
message. Window size, iterations and Gaussian widths follow SqueezeSeg's KITTI configuration.
"""

import torch
import torch.nn as nn
import torch.nn.functional as F


class RecurrentCRF(nn.Module):
    def __init__(self, classes: int, iterations: int = 3, window=(3, 5), theta_a=0.9, theta_b=0.015,
                 theta_g=0.9, w_bilateral=0.1, w_spatial=0.02):
        super().__init__()
        self.iterations, self.window = iterations, window
        self.theta_b = theta_b
        kh, kw = window
        ys, xs = torch.meshgrid(torch.arange(kh) - kh // 2, torch.arange(kw) - kw // 2, indexing="ij")
        d2 = (ys.float() ** 2 + xs.float() ** 2)
        ang_a = torch.exp(-d2 / (2 * theta_a ** 2))
        ang_g = torch.exp(-d2 / (2 * theta_g ** 2))
        ang_a[kh // 2, kw // 2] = 0
        ang_g[kh // 2, kw // 2] = 0
        self.register_buffer("ang_a", ang_a.flatten())
        self.register_buffer("ang_g", ang_g.flatten())
        self.w_bilateral = nn.Parameter(torch.full((classes,), w_bilateral))
        self.w_spatial = nn.Parameter(torch.full((classes,), w_spatial))
        self.compat = nn.Conv2d(classes, classes, 1, bias=False)
        nn.init.constant_(self.compat.weight, 0.0)
        with torch.no_grad():
            self.compat.weight.add_(1.0 - torch.eye(classes).view(classes, classes, 1, 1))

    def _unfold(self, x):
        kh, kw = self.window
        n, c, h, w = x.shape
        return F.unfold(x, self.window, padding=(kh // 2, kw // 2)).view(n, c, kh * kw, h, w)

    def forward(self, logits, xyz, mask):
        if xyz is None or mask is None:
            return logits
        m = mask.unsqueeze(1).float()
        nb = self._unfold(xyz)                       # N x 3 x K x H x W
        dist2 = ((nb - xyz.unsqueeze(2)) ** 2).sum(1)  # N x K x H x W
        nbm = self._unfold(m)[:, 0]                  # neighbours present
        bilateral = torch.exp(-dist2 / (2 * self.theta_b ** 2 + 1e-12)) * self.ang_a.view(1, -1, 1, 1) * nbm
        spatial = self.ang_g.view(1, -1, 1, 1) * nbm
        q = logits
        for _ in range(self.iterations):
            p = F.softmax(q, 1) * m
            pn = self._unfold(p)                     # N x C x K x H x W
            msg_b = (pn * bilateral.unsqueeze(1)).sum(2)
            msg_s = (pn * spatial.unsqueeze(1)).sum(2)
            msg = msg_b * self.w_bilateral.view(1, -1, 1, 1) + msg_s * self.w_spatial.view(1, -1, 1, 1)
            q = logits - self.compat(msg)
        return q

