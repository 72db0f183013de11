#!/usr/bin/env python3
"""Writes a YOLOv8n-sized detection network with random weights as ONNX, for bench_detector's
inference timing (Debian's python3-torch; nothing downloaded). The architecture follows the published
YOLOv8n layout (width 0.25, depth 0.33): a CSP backbone of C2f blocks with SPPF, a PAN neck and a
decoupled anchor-free head with distribution focal loss boxes on strides 8, 16, 32; batch norm folded
into the convolutions, as exports do. Output [1, 4 + 80, 8400] for 640x640: the YOLOv8 layout the
detector decodes. The classification bias starts at -10, so that (like a trained model) few
candidates pass the score threshold.

    yolo_random_model.py OUT.onnx [--size 640]   prints parameters and GFLOPs"""
import argparse

import torch
from torch import nn


class Conv(nn.Module):  # convolution (batch norm folded in) + SiLU
    def __init__(self, c1, c2, k=1, s=1):
        super().__init__()
        self.conv = nn.Conv2d(c1, c2, k, s, k // 2, bias=True)
        self.act = nn.SiLU()

    def forward(self, x):
        return self.act(self.conv(x))


class Bottleneck(nn.Module):
    def __init__(self, c, shortcut):
        super().__init__()
        self.a, self.b, self.add = Conv(c, c, 3), Conv(c, c, 3), shortcut

    def forward(self, x):
        y = self.b(self.a(x))
        return x + y if self.add else y


class C2f(nn.Module):  # split, n bottlenecks on one half, every intermediate concatenated
    def __init__(self, c1, c2, n, shortcut):
        super().__init__()
        self.c = c2 // 2
        self.cv1 = Conv(c1, 2 * self.c)
        self.cv2 = Conv((2 + n) * self.c, c2)
        self.m = nn.ModuleList(Bottleneck(self.c, shortcut) for _ in range(n))

    def forward(self, x):
        y = list(self.cv1(x).split((self.c, self.c), 1))
        for m in self.m:
            y.append(m(y[-1]))
        return self.cv2(torch.cat(y, 1))


class SPPF(nn.Module):
    def __init__(self, c1, c2):
        super().__init__()
        c = c1 // 2
        self.cv1, self.cv2 = Conv(c1, c), Conv(4 * c, c2)
        self.pool = nn.MaxPool2d(5, 1, 2)

    def forward(self, x):
        y = [self.cv1(x)]
        for _ in range(3):
            y.append(self.pool(y[-1]))
        return self.cv2(torch.cat(y, 1))


class Head(nn.Module):  # per level: box distributions (4 x 16 bins) and class scores
    def __init__(self, nc, chs, size, bins=16):
        super().__init__()
        self.nc, self.bins = nc, bins
        c2, c3 = max(16, chs[0] // 4, 4 * bins), max(chs[0], min(nc, 100))
        self.box = nn.ModuleList(nn.Sequential(Conv(c, c2, 3), Conv(c2, c2, 3), nn.Conv2d(c2, 4 * bins, 1)) for c in chs)
        self.cls = nn.ModuleList(nn.Sequential(Conv(c, c3, 3), Conv(c3, c3, 3), nn.Conv2d(c3, nc, 1)) for c in chs)
        for seq in self.cls:
            nn.init.constant_(seq[-1].bias, -10.0)
        anchors, strides = [], []
        for s in (8, 16, 32):
            g = size // s
            ys, xs = torch.meshgrid(torch.arange(g) + 0.5, torch.arange(g) + 0.5, indexing="ij")
            anchors.append(torch.stack((xs, ys), 0).reshape(2, -1))
            strides.append(torch.full((1, g * g), float(s)))
        self.register_buffer("anchors", torch.cat(anchors, 1).unsqueeze(0))  # [1, 2, A]
        # [1, 4, A], not [1, 1, A]: OpenCV 4.6 cannot broadcast a constant over the channels.
        self.register_buffer("strides", torch.cat(strides, 1).unsqueeze(0).expand(1, 4, -1).contiguous())
        # The expectation over the bins as a fixed 1x1 convolution (OpenCV 4.6 cannot broadcast a
        # product over the bins and sum it).
        self.dfl = nn.Conv2d(bins, 1, 1, bias=False).requires_grad_(False)
        self.dfl.weight.data[:] = torch.arange(bins, dtype=torch.float32).view(1, bins, 1, 1)

    def forward(self, feats):
        box = torch.cat([b(f).flatten(2) for b, f in zip(self.box, feats)], 2)  # [1, 64, A]
        cls = torch.cat([c(f).flatten(2) for c, f in zip(self.cls, feats)], 2)  # [1, nc, A]
        a = box.shape[2]
        prob = box.reshape(1, 4, self.bins, a).softmax(2).transpose(2, 1)  # [1, bins, 4, A]
        dist = self.dfl(prob).reshape(1, 4, a)  # [1, 4, A]: l t r b
        lt, rb = dist[:, :2], dist[:, 2:]
        x1y1, x2y2 = self.anchors - lt, self.anchors + rb
        xywh = torch.cat(((x1y1 + x2y2) / 2, x2y2 - x1y1), 1) * self.strides
        return torch.cat((xywh, cls.sigmoid()), 1)


class YoloV8n(nn.Module):
    def __init__(self, nc=80, size=640):
        super().__init__()
        self.b0 = nn.Sequential(Conv(3, 16, 3, 2), Conv(16, 32, 3, 2), C2f(32, 32, 1, True),
                                Conv(32, 64, 3, 2), C2f(64, 64, 2, True))  # P3
        self.b1 = nn.Sequential(Conv(64, 128, 3, 2), C2f(128, 128, 2, True))  # P4
        self.b2 = nn.Sequential(Conv(128, 256, 3, 2), C2f(256, 256, 1, True), SPPF(256, 256))  # P5
        self.up = nn.Upsample(scale_factor=2, mode="nearest")
        self.n4, self.n3 = C2f(384, 128, 1, False), C2f(192, 64, 1, False)
        self.d3, self.p4 = Conv(64, 64, 3, 2), C2f(192, 128, 1, False)
        self.d4, self.p5 = Conv(128, 128, 3, 2), C2f(384, 256, 1, False)
        self.head = Head(nc, (64, 128, 256), size)

    def forward(self, x):
        p3 = self.b0(x)
        p4 = self.b1(p3)
        p5 = self.b2(p4)
        t4 = self.n4(torch.cat((self.up(p5), p4), 1))
        o3 = self.n3(torch.cat((self.up(t4), p3), 1))
        o4 = self.p4(torch.cat((self.d3(o3), t4), 1))
        o5 = self.p5(torch.cat((self.d4(o4), p5), 1))
        return self.head([o3, o4, o5])


def gflops(model, size):
    total = [0]

    def hook(m, inp, out):
        total[0] += 2 * out.numel() * (m.in_channels // m.groups) * m.kernel_size[0] * m.kernel_size[1]

    hs = [m.register_forward_hook(hook) for m in model.modules() if isinstance(m, nn.Conv2d)]
    with torch.no_grad():
        model(torch.zeros(1, 3, size, size))
    for h in hs:
        h.remove()
    return total[0] / 1e9


def drop_identities(path):
    """torch's export leaves Identity nodes on constants, which OpenCV 4.6's importer refuses: their
    consumers read the Identity's input instead (what an ONNX simplifier does)."""
    import onnx
    model = onnx.load(path)
    graph = model.graph
    outputs = {o.name for o in graph.output}
    alias = {}
    keep = []
    for node in graph.node:
        if node.op_type == "Identity" and node.output[0] not in outputs:
            alias[node.output[0]] = node.input[0]
        else:
            keep.append(node)
    for node in keep:
        for i, name in enumerate(node.input):
            while name in alias:
                name = alias[name]
            node.input[i] = name
    del graph.node[:]
    graph.node.extend(keep)
    onnx.save(model, path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=640)
    a = ap.parse_args()
    torch.manual_seed(0)
    model = YoloV8n(size=a.size).eval()
    params = sum(p.numel() for p in model.parameters())
    flops = gflops(model, a.size)
    with torch.no_grad():
        torch.onnx.export(model, torch.zeros(1, 3, a.size, a.size), a.out, opset_version=12,
                          input_names=["images"], output_names=["output0"])
    drop_identities(a.out)
    print(f"parameters {params / 1e6:.2f} M, {flops:.1f} GFLOPs at {a.size}x{a.size}")


if __name__ == "__main__":
    main()
