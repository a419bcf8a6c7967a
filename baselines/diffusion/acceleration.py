"""Faster no-grad inference for the Diffusion Policy's denoiser on CPU: TorchScript, ``torch.compile``, ONNX Runtime,
OpenVINO.

:meth:`~steer_envs.baselines.diffusion.modeling.DiffusionPolicy.accelerate`
picks a mode of :data:`ACCELERATIONS`; ``"auto"`` is ONNX Runtime where it is
installed (the fastest float32 mode on CPU) and a trace (eager's plans, bit for
bit) elsewhere (:func:`resolve_acceleration`). ``"openvino"`` is the fastest on a
CPU with native bfloat16 (AMX or AVX512-BF16), where it computes in bfloat16 and
so moves the plans by bfloat16 rounding; ``"fastest"`` chooses it where it is
installed (``"auto"`` never does). ``"openvino-f32"``, ``"openvino-bf16"`` and
``"openvino-int8"`` fix OpenVINO's precision; int8 is NNCF's post-training
quantization of the export, calibrated on the first
:data:`CALIBRATION_CALLS` network calls of each input shape (run in float32
meanwhile), so it quantizes for the inputs the policy actually sees.
"""

from __future__ import annotations

import importlib.util
import logging
import operator
import threading
import warnings
from collections.abc import Callable
from typing import Any, Self, cast

import torch
from torch import nn

from steer_envs.baselines.diffusion.export import ExportDenoiser
from steer_envs.baselines.diffusion.network import DiffusionNet
from steer_envs.core.extras import MissingExtraError, install_command
from steer_envs.core.validation import one_of

__all__ = [
    "ACCELERATIONS",
    "CALIBRATION_CALLS",
    "OPENVINO_MODES",
    "AcceleratedNetwork",
    "FastNetwork",
    "accelerated",
    "onnx_missing",
    "openvino_missing",
    "openvino_precision",
    "resolve_acceleration",
]

#: OpenVINO's modes: its precision for this CPU (:func:`openvino_precision`), or a fixed one
OPENVINO_MODES: tuple[str, ...] = ("openvino", "openvino-f32", "openvino-bf16", "openvino-int8")
#: the modes of :meth:`DiffusionPolicy.accelerate`.
ACCELERATIONS: tuple[str, ...] = ("auto", "fastest", "none", "compile", "onnx", "trace", *OPENVINO_MODES)
#: the ``"fastest"`` choices already logged in this process
_LOGGED_CHOICES: set[str] = set()
#: network calls per input shape that ``"openvino-int8"`` runs in float32 and calibrates its quantization on
CALIBRATION_CALLS = 32
#: the most input shapes whose traces (or ONNX exports) one policy keeps.
MAX_TRACES = 16
_version = operator.attrgetter("_version")
#: torch.onnx.export and torch.jit.trace keep global state: one export or trace at a time in a process
_BUILD_LOCK = threading.Lock()


def onnx_missing() -> list[str]:
    """The packages ``"onnx"`` mode needs that are not installed (``onnx``, ``onnxruntime``)."""
    return [name for name in ("onnx", "onnxruntime") if importlib.util.find_spec(name) is None]


def openvino_missing(mode: str = "openvino") -> list[str]:
    """The packages an OpenVINO ``mode`` needs that are not installed (``onnx``, ``openvino``; ``nncf`` for int8)."""
    needs = ("onnx", "openvino", "nncf") if mode == "openvino-int8" else ("onnx", "openvino")
    return [name for name in needs if importlib.util.find_spec(name) is None]


def openvino_precision() -> str:
    """The precision ``"openvino"`` mode computes in here: ``"bf16"`` on a CPU with native bfloat16, else ``"f32"``."""
    import openvino as ov

    return "bf16" if "BF16" in ov.Core().get_property("CPU", "OPTIMIZATION_CAPABILITIES") else "f32"


def resolve_acceleration(mode: str, *, owner: str = "accelerate") -> str:
    """``mode`` checked against :data:`ACCELERATIONS`, with the two choosing modes resolved.

    ``"auto"`` (float32, eager's plans up to rounding) becomes ``"onnx"``, or
    ``"trace"`` without ONNX Runtime; ``"fastest"`` becomes ``"openvino"`` where
    OpenVINO is installed, else what ``"auto"`` becomes. ``ValueError`` naming
    ``owner`` for another mode.
    """
    mode = one_of(mode, "mode", ACCELERATIONS, owner=owner)
    if mode == "fastest":
        return _fastest()
    if mode == "auto":
        return "trace" if onnx_missing() else "onnx"
    return mode


def _fastest() -> str:
    """What ``"fastest"`` is on this machine; each choice is logged once per process with the CPU it was made on."""
    if openvino_missing():
        choice, why = ("trace", "neither OpenVINO nor ONNX Runtime") if onnx_missing() else ("onnx", "no OpenVINO")
    else:
        choice, why = "openvino", f"OpenVINO in {openvino_precision()}"
    if choice not in _LOGGED_CHOICES:
        from steer_envs.utils.cpu import cpu_summary

        _LOGGED_CHOICES.add(choice)
        logging.getLogger(__name__).info("accelerate='fastest' is %r here (%s) on %s", choice, why, cpu_summary())
    return choice


def accelerated(policy: Any, mode: str, *, owner: str = "accelerate") -> Any:
    """``policy`` with its denoiser in ``mode`` (unchanged if it already is); returns ``policy``.

    A policy without an ``accelerate`` method (ACT, a test double) is returned
    as is for ``"auto"``, ``"fastest"`` and ``"none"``; another mode is a ``TypeError`` naming ``owner``.
    """
    resolved = resolve_acceleration(mode, owner=owner)
    speed_up = getattr(policy, "accelerate", None)
    if not callable(speed_up):
        if mode in ("auto", "fastest", "none"):
            return policy
        raise TypeError(f"{owner}: mode {mode!r} needs a policy with an accelerate method, got {type(policy).__name__}")
    if getattr(policy, "acceleration", None) != resolved:
        speed_up(resolved)
    return policy


class FastNetwork:
    """A faster ``model(x, t, cond)`` for no-grad eval calls: ``torch.compile``, TorchScript or ONNX Runtime.

    ``"compile"`` compiles ``model`` once (static shapes: each new input shape
    compiles again, up to dynamo's recompile limit); ``"trace"`` traces it per
    input shape; ``"onnx"`` exports it to ONNX (any batch size) and runs it in an
    ONNX Runtime session on as many threads as torch uses; ``"openvino"`` compiles
    that export with OpenVINO per input shape (faster there than a free batch
    size) in :func:`openvino_precision`. Compile and trace read
    the model's parameters live; the exports hold a copy, redone when a
    parameter or buffer changes in place (a training step, ``load_state_dict``).
    Another model object starts afresh.
    """

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self._model: nn.Module | None = None
        self._compiled: Callable[..., torch.Tensor] | None = None
        self._traces: dict[tuple[Any, ...], Callable[..., torch.Tensor]] = {}
        self._sessions: dict[tuple[Any, ...], tuple[int, Any]] = {}
        self._tensors: list[torch.Tensor] = []  # the model's parameters and buffers, whose versions the export tracks
        self._calibration: dict[tuple[Any, ...], list[dict[str, Any]]] = {}  # int8: feeds seen per input key

    def __call__(self, model: nn.Module, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """``model(x, t, cond)``; ``t (1 or n,)`` and ``cond (1 or n, c)`` (one row: shared by the batch)."""
        if self._model is not model:
            self._model, self._compiled = model, None
            self._traces.clear()
            self._sessions.clear()
            self._tensors = [*model.parameters(), *model.buffers()]
        if self.mode == "compile" and self._compiled is None:
            self._compiled = cast(Callable[..., torch.Tensor], torch.compile(model, dynamic=False))
        if self.mode == "onnx" or self.mode in OPENVINO_MODES:
            return self._run_onnx(model, x, t, cond)
        n = x.shape[0]
        t, cond = t.expand(n), cond.expand(n, -1)
        if self._compiled is not None:
            return self._compiled(x, t, cond)
        key = tuple((a.shape, a.dtype, a.device) for a in (x, t, cond))
        traced = self._traces.get(key)
        if traced is None:
            with _BUILD_LOCK:  # threads sharing this policy (steer-ui sessions) may ask for the same shape at once
                traced = self._traces.get(key)
                if traced is None:
                    if len(self._traces) >= MAX_TRACES:
                        del self._traces[next(iter(self._traces))]
                    with warnings.catch_warnings():  # torch.jit is deprecated upstream; a trace per input shape
                        warnings.simplefilter("ignore", DeprecationWarning)
                        warnings.simplefilter("ignore", torch.jit.TracerWarning)
                        traced = torch.jit.trace(model, (x, t, cond), check_trace=False)
                    self._traces[key] = traced
        return traced(x, t, cond)

    def _run_onnx(self, model: nn.Module, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        n = x.shape[0]
        shared = t.numel() == 1 and cond.shape[0] == 1 and x.device.type == "cpu" and _is_diffusion_net(model)
        if not shared:
            t, cond = t.expand(n), cond.expand(n, -1)
        if x.device.type != "cpu":  # CPU runtimes only; elsewhere the network runs as is
            return cast(torch.Tensor, model(x, t, cond))
        # ONNX Runtime: one export serves any batch size; OpenVINO compiles each input shape
        size = tuple(x.shape) if self.mode in OPENVINO_MODES else tuple(x.shape[1:])
        key: tuple[Any, ...] = (size, tuple(cond.shape[1:]), x.dtype, t.dtype, cond.dtype, shared)
        feeds = {"x": x.detach().numpy(), "t": t.detach().reshape(-1).numpy(), "cond": cond.detach().numpy()}
        mode = self.mode
        if mode == "openvino-int8":
            seen = self._calibration.setdefault(key, [])
            if len(seen) < CALIBRATION_CALLS:  # float32 until the shape's calibration set is full
                seen.append({k: v.copy() for k, v in feeds.items()})
                key, mode = (*key, "calibrating"), "openvino-f32"
        versions = sum(map(_version, self._tensors))  # version counters only grow: any change raises the sum
        entry = self._sessions.get(key)
        if entry is None or entry[0] != versions:
            with _BUILD_LOCK:  # threads sharing this policy (steer-ui sessions) may ask for the same export at once
                entry = self._sessions.get(key)
                if entry is None or entry[0] != versions:
                    if entry is None and len(self._sessions) >= MAX_TRACES:
                        del self._sessions[next(iter(self._sessions))]
                    if mode == "onnx":
                        session = _onnx_session(model, x, t.reshape(-1), cond, shared=shared)
                    else:
                        calibration = self._calibration.get(key) if mode == "openvino-int8" else None
                        session = _openvino_model(
                            model, x, t.reshape(-1), cond, shared=shared, mode=mode, calibration=calibration
                        )
                    self._sessions[key] = entry = (versions, session)
        return torch.from_numpy(entry[1].run(None, feeds)[0])


class _Conv1dAs2d(nn.Module):
    """A ``Conv1d`` computed as a ``(1, k)`` 2-D convolution, for export only.

    ONNX Runtime's CPU provider has blocked-layout (NCHWc) kernels for 2-D
    convolutions only; on the denoiser's narrow channels they are ~1.2x faster
    per network call than its 1-D path (same outputs, float32 rounding apart).
    """

    def __init__(self, conv: nn.Conv1d) -> None:
        super().__init__()
        self.conv = conv

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        c = self.conv
        y = nn.functional.conv2d(
            x.unsqueeze(2),
            c.weight.unsqueeze(2),
            c.bias,
            stride=(1, c.stride[0]),
            padding=(0, cast(tuple[int, ...], c.padding)[0]),
            dilation=(1, c.dilation[0]),
            groups=c.groups,
        )
        return y.squeeze(2)


def _for_export(model: nn.Module) -> nn.Module:
    """A copy of ``model`` whose zero-padded ``Conv1d`` layers run as 2-D convolutions (:class:`_Conv1dAs2d`)."""
    import copy

    model = copy.deepcopy(model)
    for module in list(model.modules()):
        for child_name, child in list(module.named_children()):
            if isinstance(child, nn.Conv1d) and child.padding_mode == "zeros" and not isinstance(child.padding, str):
                setattr(module, child_name, _Conv1dAs2d(child))
    return model


def _is_diffusion_net(model: nn.Module) -> bool:
    return isinstance(model, DiffusionNet)


def _onnx_graph(model: nn.Module, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor, *, shared: bool) -> bytes:
    """``model`` exported to ONNX at ``(x, t, cond)``'s shapes with a free batch size (the serialized graph).

    A :class:`~steer_envs.baselines.diffusion.modeling.DiffusionNet` is exported
    through :class:`~steer_envs.baselines.diffusion.export.ExportDenoiser` (with
    ``shared``: one ``t`` and ``cond`` row for the batch); another model as is,
    its ``Conv1d`` layers as 2-D convolutions (``shared`` must then be false).
    """
    import os
    import tempfile

    exported = ExportDenoiser(model, shared_condition=shared) if _is_diffusion_net(model) else _for_export(model)
    axes = {"x": {0: "n"}, "out": {0: "n"}} | ({} if shared else {"t": {0: "n"}, "cond": {0: "n"}})

    # the TorchScript-based exporter (deprecated upstream, silenced here) needs no onnxscript
    with tempfile.TemporaryDirectory(prefix="steer-envs-onnx-") as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", FutureWarning)
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        # InstanceNormalization computes its own statistics in ONNX, which is GroupNorm's eval behaviour
        warnings.filterwarnings("ignore", message=r".*'instance_norm' is set to train=True", category=UserWarning)
        path = os.path.join(folder, "denoiser.onnx")
        torch.onnx.export(
            exported,
            (x, t, cond),
            path,
            input_names=["x", "t", "cond"],
            output_names=["out"],
            dynamic_axes=axes,
            opset_version=17,
            dynamo=False,
        )
        with open(path, "rb") as file:
            return file.read()


def _onnx_session(model: nn.Module, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor, *, shared: bool) -> Any:
    """An ONNX Runtime session of :func:`_onnx_graph`'s export (any batch size), on torch's thread count."""
    import onnxruntime as ort

    graph = _onnx_graph(model, x, t, cond, shared=shared)
    options = ort.SessionOptions()
    options.intra_op_num_threads = torch.get_num_threads()
    options.inter_op_num_threads = 1
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")  # no spin-waits on a shared CPU
    options.log_severity_level = 3
    return ort.InferenceSession(graph, options, providers=["CPUExecutionProvider"])


def _openvino_model(
    model: nn.Module,
    x: torch.Tensor,
    t: torch.Tensor,
    cond: torch.Tensor,
    *,
    shared: bool,
    mode: str = "openvino",
    calibration: list[dict[str, Any]] | None = None,
) -> Any:
    """:func:`_onnx_graph`'s export compiled by OpenVINO for ``x``'s exact shape, on torch's thread count.

    ``mode``'s precision (``"openvino"``: :func:`openvino_precision`); ``"openvino-int8"`` quantizes the
    graph with NNCF on ``calibration`` (feeds of this shape) and runs what stays float in
    :func:`openvino_precision`. No thread pinning (other processes of a bench run share the cores), one
    stream, latency mode.
    """
    import openvino as ov

    core = ov.Core()
    graph = core.read_model(_onnx_graph(model, x, t, cond, shared=shared), b"")  # ONNX bytes, weights inside
    graph.reshape({"x": list(x.shape), "t": list(t.shape), "cond": list(cond.shape)})
    precision = {"openvino-f32": "f32", "openvino-bf16": "bf16"}.get(mode, openvino_precision())
    if mode == "openvino-int8":
        graph = _quantized(graph, calibration or [])
    config = {
        "INFERENCE_NUM_THREADS": torch.get_num_threads(),
        "INFERENCE_PRECISION_HINT": precision,
        "PERFORMANCE_HINT": "LATENCY",
        "NUM_STREAMS": 1,
        "ENABLE_CPU_PINNING": False,
    }
    return _OpenVinoRunner(core.compile_model(graph, "CPU", config))


def _quantized(graph: Any, calibration: list[dict[str, Any]]) -> Any:
    """``graph`` with int8 weights and activations: NNCF's post-training quantization on ``calibration``."""
    import nncf

    if not calibration:
        raise ValueError("openvino-int8: no calibration feeds for this input shape")
    nncf_log = logging.getLogger("nncf")
    level = nncf_log.level
    nncf_log.setLevel(logging.WARNING)  # its progress bars and INFO lines would flood a benchmark's output
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return nncf.quantize(
                graph, nncf.Dataset(calibration), subset_size=len(calibration), fast_bias_correction=True
            )
    finally:
        nncf_log.setLevel(level)


class _OpenVinoRunner:
    """A compiled OpenVINO model run as an ONNX Runtime session is (:meth:`run`), from any thread.

    Each call borrows an infer request from a pool.
    """

    def __init__(self, compiled: Any) -> None:
        import queue

        self.compiled = compiled
        self._requests: queue.SimpleQueue[Any] = queue.SimpleQueue()

    def run(self, output_names: None, feeds: dict[str, Any]) -> list[Any]:
        """``[output]`` for ``feeds``, as ``InferenceSession.run(None, feeds)`` returns it."""
        import queue

        try:
            request = self._requests.get_nowait()
        except queue.Empty:
            request = self.compiled.create_infer_request()
        try:
            return [request.infer(feeds)[self.compiled.output(0)].copy()]  # the request reuses its output buffer
        finally:
            self._requests.put(request)


class AcceleratedNetwork:
    """What a policy with a :class:`~steer_envs.baselines.diffusion.network.DiffusionNet` gets to run it faster.

    Diffusion Policy and the flow-matching policy mix it in: :meth:`accelerate`
    picks a mode of :data:`ACCELERATIONS`, :attr:`acceleration` says which, and
    the policy calls :meth:`_network` where it would call ``self.model``. The
    class sets ``self._fast`` to ``None`` (eager) until :meth:`accelerate` runs.
    """

    model: nn.Module
    _fast: FastNetwork | None = None

    def accelerate(self, mode: str) -> Self:
        """Run the network of inference calls eagerly (``"none"``, the default) or faster (:data:`ACCELERATIONS`).

        ``"trace"``: a ``torch.jit.trace`` per input shape (~1 s each; the same
        plans as eager, bit for bit). ``"compile"``: ``torch.compile(model,
        dynamic=False)`` (~1 min per batch size; fused kernels round
        differently: plans of the shipped checkpoint within ~2e-5, more where
        SS's re-noising amplifies it). ``"onnx"``: an ONNX export run by ONNX
        Runtime on CPU (~1 s per plan shape, any batch size; the fastest of the
        three on CPU, float32 rounding apart the eager plans; needs the
        ``onnx`` extra). ``"openvino"``: that export compiled by OpenVINO per
        input shape, in bfloat16 on a CPU with native bfloat16 (AMX,
        AVX512-BF16: the fastest mode there, plans within bfloat16 rounding of
        eager's), float32 elsewhere; needs the ``openvino`` extra;
        ``"openvino-f32"`` / ``"openvino-bf16"`` fix the precision, ``"openvino-int8"``
        quantizes with NNCF, calibrated on the first calls of each input shape. ``"auto"``:
        ``"onnx"`` where ONNX Runtime is installed, else ``"trace"``;
        ``"fastest"``: ``"openvino"`` where it is installed, else as ``"auto"``
        (:attr:`acceleration` says which). Only no-grad calls in eval mode (``sample``, the ITPS
        samplers' ``predict_noise`` / ``predict_velocity``) are accelerated; gradient calls and
        training run eagerly. Weights are followed (after replacing parameter
        objects, call again). Returns self; ``ValueError`` for another ``mode``,
        ``ImportError`` naming the extra when ``"onnx"`` or ``"openvino"`` lacks its packages.
        """
        owner = f"{type(self).__name__}.accelerate"
        mode = resolve_acceleration(mode, owner=owner)
        if mode == "onnx" or mode in OPENVINO_MODES:
            missing = onnx_missing() if mode == "onnx" else openvino_missing(mode)
            extra = "onnx" if mode == "onnx" else "openvino"
            if missing:
                raise MissingExtraError(
                    f"{owner}: mode {mode!r} needs {' and '.join(missing)}, "
                    f"which is not installed: {install_command(extra)}",
                    name=missing[0],
                    extra=extra,
                )
        self._fast = None if mode == "none" else FastNetwork(mode)
        return self

    @property
    def acceleration(self) -> str:
        """The mode set by :meth:`accelerate` (``"none"`` by default)."""
        return "none" if self._fast is None else self._fast.mode

    def _network(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """``model(x, t, cond)`` for ``t`` and ``cond`` of 1 or ``n`` rows, accelerated (:meth:`accelerate`) when
        gradients are off and the model is in eval (one shared row then runs the condition path once)."""
        if self._fast is None or torch.is_grad_enabled() or self.model.training:
            n = x.shape[0]
            return self.model(x, t.expand(n), cond.expand(n, -1))
        return self._fast(self.model, x, t, cond)
