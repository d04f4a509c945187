"""The paper's Figure 3 graph CNN and the conversion of contact graphs into its input.

The torch-free helpers (stratified split, graphs read back from a store,
training-curve plot) live in :mod:`query.learn.training_data` and are re-exported here.
Building, converting and training need the ``learn`` extra (torch,
torch_geometric), imported inside the functions only.

Network (Fig. 3 of the paper, 4 input channels)::

    x (n, 4) ──┬── conv1 (4 -> 128) ── BN ── ReLU ── h1 (n, 128) ──┐
               │                                                   ├─ cat (n, 256)
               └──────────────── conv2 (h1: 128 -> 128) ── BN ── ReLU ── h2 (n, 128) ─┘
    cat ── MLP (256 -> 256) ── global max pool (B, 256) ── FC (256 -> 128) ── FC (128 -> classes)

With ``graph_features = d > 0`` the network also reads a graph-level input ``u``
(B, d) (the shape descriptor, standardised), concatenated to the pooled vector
before the first fully connected layer (256 + d -> 128).

The two convolutions are stacked (the second reads the first's output) and both
outputs are concatenated, as in the paper's figure. ``conv`` picks the operator:

- ``"tag"``: :class:`torch_geometric.nn.TAGConv` (K = 3 hops), edge weight 1/deg.
- ``"arma"``: :class:`torch_geometric.nn.ARMAConv` (2 stacks, 1 layer), edge weight 1/deg.
- ``"spline"``: :class:`SplineConv1d`, the SplineConv operator for 1-D pseudo-coordinates
  (the edge attribute 1/deg) with open, degree-1 B-splines, in plain PyTorch. PyG 2.8's
  own ``SplineConv`` needs ``pyg-lib`` (``torch-spline-conv`` is ignored since PyG 2.7),
  and pyg-lib is not published on PyPI for CPU builds of torch, so it is not installable
  here; for this case the two compute the same function.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.learn.training_data import StoredGraph, plot_history, stored_graphs, stratified_split
from shapedb.errors import ConfigError, InvalidShapeError, require

if TYPE_CHECKING:  # pragma: no cover
    import torch

__all__ = [
    "CONVOLUTIONS",
    "import_torch",
    "node_features",
    "edge_arrays",
    "to_data",
    "random_rotations",
    "build_network",
    "count_parameters",
    "train_network",
    "stratified_split",
    "StoredGraph",
    "stored_graphs",
    "plot_history",
]

CONVOLUTIONS = ("tag", "arma", "spline")


def import_torch() -> tuple[Any, Any]:
    """Import torch and torch_geometric, or raise :class:`MissingDependencyError`.

    Returns
    -------
    (torch, torch_geometric) : tuple of modules
    """
    torch = require("torch", extra="learn", feature="shape classification")
    with warnings.catch_warnings():
        # torch 2.13 deprecates torch.jit.script, which torch_geometric 2.8 calls on import.
        warnings.filterwarnings(
            "ignore", message=".*torch.jit.script.*", category=DeprecationWarning
        )
        warnings.filterwarnings(
            "ignore", message=".*is no longer necessary.*", category=DeprecationWarning
        )
        pyg = require("torch_geometric", extra="learn", feature="shape classification")
        import torch_geometric.loader  # noqa: F401
        import torch_geometric.nn  # noqa: F401
    return torch, pyg


def node_features(centers: NDArray[np.float64], radii: NDArray[np.float64]) -> NDArray[np.float32]:
    """Node attributes [c, r/r1] with centres normalised for position and size.

    Centres are translated to the volume-weighted centroid of the balls and divided
    by the bounding radius max_i(|c_i - centroid| + r_i), so every shape fits the unit
    ball whatever its units and position (the balls of a mesh and of a point cloud of
    the same shape then land on the same coordinates).

    Parameters
    ----------
    centers : (n, 3) float
    radii : (n,) float, non-increasing, positive

    Returns
    -------
    (n, 4) float32
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if len(r) == 0 or len(c) != len(r):
        raise InvalidShapeError(
            f"graph has {len(c)} centres and {len(r)} radii; need n >= 1 of each"
        )
    w = r**3
    centroid = (w[:, None] * c).sum(0) / max(float(w.sum()), 1e-300)
    d = c - centroid
    scale = float((np.linalg.norm(d, axis=1) + r).max())
    scale = scale if scale > 0 else 1.0
    out = np.empty((len(r), 4), dtype=np.float32)
    out[:, :3] = d / scale
    out[:, 3] = r / max(float(r.max()), 1e-300)
    return out


def edge_arrays(
    edges: NDArray[np.integer], n: int
) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
    """Both directions of each contact and the paper's edge attribute 1/deg(source).

    Parameters
    ----------
    edges : (m, 2) int
        Undirected contact edges.
    n : int
        Number of nodes.

    Returns
    -------
    edge_index : (2, 2m) int64
    edge_attr : (2m,) float32, 1/deg of the message's source node
    """
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if len(e) and (e.min() < 0 or e.max() >= n):
        raise InvalidShapeError(f"edge index out of range for a graph of {n} nodes")
    index = np.concatenate([e.T, e[:, ::-1].T], axis=1) if len(e) else np.zeros((2, 0), np.int64)
    deg = np.bincount(index[0], minlength=n).astype(np.float64)
    attr = (1.0 / np.maximum(deg[index[0]], 1.0)).astype(np.float32)
    return np.ascontiguousarray(index), attr


def to_data(graph: Any, y: int | None = None, u: NDArray[np.floating] | None = None) -> Any:
    """Convert a Decomposition or ContactGraph into a :class:`torch_geometric.data.Data`.

    Parameters
    ----------
    graph : Decomposition or ContactGraph (anything with centers, radii, edges)
    y : int, optional
        Class index.
    u : (d,) float, optional
        Graph-level input (the standardised descriptor).

    Returns
    -------
    torch_geometric.data.Data
        ``x`` (n, 4) float32 [c normalised, r/r1]; ``edge_index`` (2, 2m) int64;
        ``edge_attr`` (2m, 1) float32 = 1/deg(source); ``y`` (1,) int64 and
        ``u`` (1, d) float32 if given.
    """
    torch, pyg = import_torch()
    x = node_features(graph.centers, graph.radii)
    index, attr = edge_arrays(graph.edges, len(x))
    data = pyg.data.Data(
        x=torch.from_numpy(x),
        edge_index=torch.from_numpy(index),
        edge_attr=torch.from_numpy(attr).unsqueeze(1),
    )
    if y is not None:
        data.y = torch.tensor([int(y)], dtype=torch.long)
    if u is not None:
        data.u = torch.as_tensor(np.asarray(u, dtype=np.float32).reshape(1, -1))
    return data


def random_rotations(k: int, generator: torch.Generator | None = None) -> torch.Tensor:
    """``k`` rotation matrices drawn uniformly from SO(3) (QR of Gaussian matrices).

    Returns (k, 3, 3) float32.
    """
    import torch

    a = torch.randn(k, 3, 3, generator=generator)
    q, r = torch.linalg.qr(a)
    q = q * torch.sign(torch.diagonal(r, dim1=-2, dim2=-1)).unsqueeze(-2)
    det = torch.linalg.det(q)
    q[:, :, 0] = q[:, :, 0] * det.sign().unsqueeze(-1)
    return q


def _csr(rows: torch.Tensor, cols: torch.Tensor, vals: torch.Tensor, size: tuple[int, int]) -> Any:
    """A torch CSR matrix from COO triplets (duplicates summed)."""
    import torch

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        coo = torch.sparse_coo_tensor(
            torch.stack([rows, cols]), vals, size, check_invariants=False
        ).coalesce()
        return coo.to_sparse_csr()


def _spline_conv_class() -> type:
    import_torch()
    import torch
    from torch import nn

    class SplineConv1d(nn.Module):
        """SplineConv (Fey et al. 2018) for 1-D pseudo-coordinates u in [0, 1].

        Open B-splines of degree 1 with ``kernel_size`` control weights
        W_k (in, out): message j -> i is sum_b B_b(u_ji) x_j W_{k_b(u_ji)}; messages are
        averaged over the incoming edges, then x_i W_root + bias is added.
        """

        def __init__(self, in_channels: int, out_channels: int, kernel_size: int = 5) -> None:
            super().__init__()
            self.in_channels, self.out_channels, self.kernel_size = (
                in_channels,
                out_channels,
                kernel_size,
            )
            self.weight = nn.Parameter(torch.empty(kernel_size, in_channels, out_channels))
            self.root = nn.Linear(in_channels, out_channels, bias=True)
            bound = 1.0 / math.sqrt(in_channels * kernel_size)
            nn.init.uniform_(self.weight, -bound, bound)

        def basis(self, edge_index: torch.Tensor, pseudo: torch.Tensor, n: int) -> tuple[Any, Any]:
            """(n, n * K) CSR matrix B, row i holding B_b(u_ji) / deg_in(i) at j*K + k_b; and B^T."""
            k = self.kernel_size
            src, dst = edge_index[0], edge_index[1]
            v = pseudo.reshape(-1).clamp(0.0, 1.0) * (k - 1)
            lo = v.floor().clamp(max=max(k - 2, 0))
            frac = v - lo
            lo = lo.long()
            hi = (lo + 1).clamp(max=k - 1)
            cnt = torch.zeros(n, dtype=v.dtype, device=v.device)
            cnt.index_add_(0, dst, torch.ones_like(v))
            inv = 1.0 / cnt.clamp(min=1)[dst]
            rows = torch.cat([dst, dst])
            cols = torch.cat([src * k + lo, src * k + hi])
            vals = torch.cat([(1 - frac) * inv, frac * inv])
            return _csr(rows, cols, vals, (n, n * k)), _csr(cols, rows, vals, (n * k, n))

        def forward(self, x: torch.Tensor, basis: tuple[Any, Any]) -> torch.Tensor:
            """``basis`` from :meth:`basis` (computed once per batch for both layers)."""
            k = self.kernel_size
            w = self.weight.permute(1, 0, 2).reshape(self.in_channels, k * self.out_channels)
            xw = (x @ w).reshape(-1, self.out_channels)  # row j*K + k is x_j W_k
            return _SpMM.apply(basis[0], basis[1], xw) + self.root(x)

    class _SpMM(torch.autograd.Function):
        """A @ X with A^T given, so the backward pass does not transpose A."""

        @staticmethod
        def forward(ctx: Any, a: Any, at: Any, x: torch.Tensor) -> torch.Tensor:  # type: ignore[override]
            ctx.at = at
            return torch.sparse.mm(a, x)

        @staticmethod
        def backward(ctx: Any, grad: torch.Tensor) -> tuple[None, None, torch.Tensor]:  # type: ignore[override]
            return None, None, torch.sparse.mm(ctx.at, grad)

    return SplineConv1d


def _network_class() -> type:
    """The Figure 3 network's module class (defined once torch is imported)."""
    _, pyg = import_torch()
    import torch
    from torch import nn

    gnn = pyg.nn

    def make(conv: str, cin: int, cout: int) -> nn.Module:
        if conv == "tag":
            return gnn.TAGConv(cin, cout, K=3)
        if conv == "arma":
            return gnn.ARMAConv(cin, cout, num_stacks=2, num_layers=1, dropout=0.0)
        return _spline_conv_class()(cin, cout, kernel_size=5)

    class MDBDNet(nn.Module):
        def __init__(
            self,
            conv: str,
            n_classes: int,
            hidden: int,
            dropout: float,
            in_channels: int,
            graph_features: int,
        ) -> None:
            super().__init__()
            self.conv_name = conv
            self.graph_features = graph_features
            self.conv1 = make(conv, in_channels, hidden)
            self.bn1 = nn.BatchNorm1d(hidden)
            self.conv2 = make(conv, hidden, hidden)
            self.bn2 = nn.BatchNorm1d(hidden)
            self.mlp = nn.Sequential(
                nn.Linear(2 * hidden, 2 * hidden), nn.BatchNorm1d(2 * hidden), nn.ReLU()
            )
            self.head = nn.Sequential(
                nn.Dropout(dropout),
                nn.Linear(2 * hidden + graph_features, hidden),
                nn.BatchNorm1d(hidden),
                nn.ReLU(),
                nn.Dropout(dropout),
                nn.Linear(hidden, n_classes),
            )

        def _operator(self, data: Any) -> tuple[Any, ...]:
            """What the convolutions read: a sparse matrix (faster on the CPU) or edges."""
            n, ei, attr = data.num_nodes, data.edge_index, data.edge_attr.reshape(-1)
            if self.conv_name == "spline":
                basis = self.conv1.basis(ei, attr, n)  # type: ignore[operator]
                return (basis,)  # one basis, shared by both layers
            if self.conv_name == "tag":  # transposed adjacency, entry (dst, src) = 1/deg(src)
                return (_csr(ei[1], ei[0], attr, (n, n)),)
            return (ei, attr)

        def embed(self, data: Any) -> torch.Tensor:
            op = self._operator(data)
            with warnings.catch_warnings():  # "sparse CSR support is in beta state"
                warnings.simplefilter("ignore", UserWarning)
                h1 = torch.relu(self.bn1(self.conv1(data.x, *op)))
                h2 = torch.relu(self.bn2(self.conv2(h1, *op)))
            h = self.mlp(torch.cat([h1, h2], dim=1))
            return gnn.global_max_pool(h, data.batch)

        def forward(self, data: Any) -> torch.Tensor:
            h = self.embed(data)
            if self.graph_features:
                h = torch.cat([h, data.u.reshape(h.shape[0], -1)], dim=1)
            return self.head(h)

    return MDBDNet


def build_network(
    conv: str,
    n_classes: int,
    *,
    hidden: int = 128,
    dropout: float = 0.5,
    in_channels: int = 4,
    graph_features: int = 0,
) -> Any:
    """The Figure 3 network as a :class:`torch.nn.Module`.

    Parameters
    ----------
    conv : {"tag", "arma", "spline"}
    n_classes : int
    hidden : int
        Channels of each graph convolution (128 in the paper); the pooled shape
        vector has 2 * hidden entries (256).
    dropout : float
        Dropout before each fully connected layer.
    in_channels : int
        Node attributes (4: [c, r/r1]).
    graph_features : int
        Length d of the graph-level input ``data.u`` (B, d) read beside the pooled
        vector; 0 for the paper's network.

    Returns
    -------
    torch.nn.Module
        ``forward(data)`` on a :class:`torch_geometric.data.Batch` returns logits
        (B, n_classes); ``embed(data)`` returns the (B, 2 * hidden) shape vectors.
    """
    if conv not in CONVOLUTIONS:
        raise ConfigError(f"conv={conv!r} is invalid: must be one of {CONVOLUTIONS}")
    if n_classes < 2:
        raise ConfigError(f"n_classes={n_classes} is invalid: need at least 2 classes")
    return _network_class()(conv, n_classes, hidden, dropout, in_channels, graph_features)


def count_parameters(model: Any) -> int:
    """Number of trainable parameters of a torch module."""
    return int(sum(p.numel() for p in model.parameters() if p.requires_grad))


def _augment(batch: Any, generator: Any) -> Any:
    """Rotate the centres of every graph of a batch by its own random rotation."""
    import torch

    rot = random_rotations(int(batch.num_graphs), generator).to(batch.x.device)
    xyz = torch.bmm(rot[batch.batch], batch.x[:, :3].unsqueeze(-1)).squeeze(-1)
    batch.x = torch.cat([xyz, batch.x[:, 3:]], dim=1)
    return batch


def _run_epoch(
    model: Any, loader: Any, opt: Any = None, gen: Any = None, rotate: bool = False
) -> tuple[float, float]:
    """One pass over ``loader``; trains when ``opt`` is given. Returns (loss, accuracy)."""
    import torch

    train = opt is not None
    model.train(train)
    total, correct, loss_sum = 0, 0, 0.0
    dev = next(model.parameters()).device
    with torch.set_grad_enabled(train):
        for batch in loader:
            batch = batch.to(dev)
            if train and rotate:
                batch = _augment(batch, gen)
            logits = model(batch)
            loss = torch.nn.functional.cross_entropy(logits, batch.y)
            if train:
                opt.zero_grad()
                loss.backward()
                opt.step()
            n = int(batch.num_graphs)
            total += n
            loss_sum += float(loss.detach()) * n
            correct += int((logits.argmax(1) == batch.y).sum())
    return loss_sum / max(total, 1), correct / max(total, 1)


def train_network(
    model: Any,
    train_set: Sequence[Any],
    val_set: Sequence[Any],
    *,
    epochs: int,
    lr: float,
    weight_decay: float,
    warmup: int,
    batch_size: int,
    rotate: bool,
    seed: int,
    callback: Any = None,
) -> tuple[dict[str, list[float]], int]:
    """Adam with linear warm-up then cosine annealing; keep the best validation epoch.

    Parameters
    ----------
    model : torch.nn.Module from :func:`build_network`, on its device
    train_set, val_set : sequences of torch_geometric Data with ``y``
    epochs, lr, weight_decay, warmup, batch_size, rotate, seed : as in GraphClassifier
    callback : callable, optional
        ``callback(epoch, epochs, metrics)`` after every epoch.

    Returns
    -------
    history : dict[str, list[float]]
        Per epoch: "loss", "accuracy", "val_loss", "val_accuracy", "lr", "seconds".
    best_epoch : int
        0-based epoch whose weights ``model`` holds on return (the best validation
        accuracy, ties broken by validation loss; the last epoch without validation).
    """
    import copy
    import time

    torch, pyg = import_torch()
    gen = torch.Generator().manual_seed(seed)
    bs = max(2, min(batch_size, len(train_set)))
    train_loader = pyg.loader.DataLoader(
        list(train_set),
        batch_size=bs,
        shuffle=True,
        drop_last=len(train_set) % bs == 1,  # BatchNorm needs two graphs
        generator=torch.Generator().manual_seed(seed),
    )
    val_loader = pyg.loader.DataLoader(list(val_set), batch_size=64) if len(val_set) else None
    opt = torch.optim.Adam(model.parameters(), lr=lr, weight_decay=weight_decay)
    warm = max(0, min(warmup, epochs - 1))

    def factor(epoch: int) -> float:
        if epoch < warm:
            return (epoch + 1) / (warm + 1)
        t = (epoch - warm) / max(1, epochs - warm)
        return 0.5 * (1 + math.cos(math.pi * t))

    sched = torch.optim.lr_scheduler.LambdaLR(opt, factor)
    keys = ("loss", "accuracy", "val_loss", "val_accuracy", "lr", "seconds")
    hist: dict[str, list[float]] = {k: [] for k in keys}
    best, best_state, best_epoch = (-1.0, -math.inf), None, epochs - 1
    for epoch in range(epochs):
        t0 = time.perf_counter()
        lr_now = opt.param_groups[0]["lr"]
        loss, acc = _run_epoch(model, train_loader, opt, gen, rotate)
        sched.step()
        vloss, vacc = _run_epoch(model, val_loader) if val_loader else (math.nan, math.nan)
        values = (loss, acc, vloss, vacc, lr_now, time.perf_counter() - t0)
        for k, v in zip(keys, values, strict=True):
            hist[k].append(float(v))
        if val_loader is not None and (vacc, -vloss) > best:
            best, best_epoch = (vacc, -vloss), epoch
            best_state = copy.deepcopy(model.state_dict())
        if callback is not None:
            callback(epoch + 1, epochs, {k: v[-1] for k, v in hist.items()})
    if best_state is not None:
        model.load_state_dict(best_state)
    model.eval()
    return hist, best_epoch
