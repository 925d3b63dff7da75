"""force_estimator node parameters: defaults, validation naming the bad parameter and value, and
the per-finger bundle choice. The node only copies ROS parameters in."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from prisma_common.hand import FINGERS
from prisma_common.parameters import ParameterError, check_fingers

from .bias import DEFAULT_CONTACT_VOLTAGE, DEFAULT_SAMPLES
from .bundle import DEFAULT_BUNDLE, DEFAULT_PRECISION, PRECISIONS

__all__ = ["ForceEstimatorConfig", "ParameterError", "FINGERS", "OVERRIDE_PREFIX"]
OVERRIDE_PREFIX = "finger_bundles."


@dataclass
class ForceEstimatorConfig:
    model_bundle: str = DEFAULT_BUNDLE  # bundle directory for every finger without an override
    # finger -> bundle directory; "" = use model_bundle. ROS parameters finger_bundles.<finger>.
    finger_bundles: dict[str, str] = field(default_factory=lambda: {f: "" for f in FINGERS})
    fingers: list[str] = field(default_factory=lambda: list(FINGERS))
    frame_id_format: str = ""  # "" = the input TaxelArray's frame id; else e.g. "prisma_{finger}_pad"
    torch_threads: int = 1  # intra-op threads of the network (process-wide)
    # "float16": float16 weights on the network's dense-chain form (CNN2; other networks run in
    # float32); "float32": the bundle's TorchScript network as it is (docs/force_estimation.md)
    network_precision: str = DEFAULT_PRECISION
    batch_window: float = 0.005  # s: samples whose stamps lie this close form one batch (one scan)
    diagnostics_period: float = 1.0  # s between /diagnostics messages
    bias_samples: int = DEFAULT_SAMPLES  # ~/bias: each finger's offset = mean of its last N estimates
    bias_contact_voltage: float = DEFAULT_CONTACT_VOLTAGE  # V: ~/bias is refused while a pad's taxel mean reaches it

    def as_parameters(self) -> dict[str, Any]:
        """Flat ROS parameter names and defaults (overrides as finger_bundles.<finger>)."""
        params: dict[str, Any] = {
            "model_bundle": self.model_bundle,
            "fingers": list(self.fingers),
            "frame_id_format": self.frame_id_format,
            "torch_threads": self.torch_threads,
            "network_precision": self.network_precision,
            "batch_window": self.batch_window,
            "diagnostics_period": self.diagnostics_period,
            "bias_samples": self.bias_samples,
            "bias_contact_voltage": self.bias_contact_voltage,
        }
        for finger in FINGERS:
            params[OVERRIDE_PREFIX + finger] = self.finger_bundles.get(finger, "")
        return params

    @classmethod
    def from_parameters(cls, values: dict[str, Any]) -> ForceEstimatorConfig:
        config = cls()
        for name, value in values.items():
            if name.startswith(OVERRIDE_PREFIX):
                config.finger_bundles[name[len(OVERRIDE_PREFIX):]] = value
            elif name == "fingers":
                config.fingers = list(value)
            elif hasattr(config, name):
                setattr(config, name, value)
        return config.validate()

    def validate(self) -> ForceEstimatorConfig:
        if not isinstance(self.model_bundle, str) or not self.model_bundle:
            raise ParameterError("model_bundle", self.model_bundle, "a bundle directory path")
        for finger, path in self.finger_bundles.items():
            if finger not in FINGERS:
                raise ParameterError(OVERRIDE_PREFIX + finger, path, f"{finger!r} is not one of {FINGERS}")
            if not isinstance(path, str):
                raise ParameterError(OVERRIDE_PREFIX + finger, path, "a bundle directory path or ''")
        check_fingers(self.fingers)
        try:
            self.frame_id_format.format(finger="thumb")
        except (KeyError, IndexError, ValueError, AttributeError) as exc:
            raise ParameterError("frame_id_format", self.frame_id_format,
                                 f"'' or a str.format pattern whose only field is {{finger}} ({exc})") from None
        if isinstance(self.torch_threads, bool) or not isinstance(self.torch_threads, int) or self.torch_threads < 1:
            raise ParameterError("torch_threads", self.torch_threads, "an integer >= 1")
        if self.network_precision not in PRECISIONS:
            raise ParameterError("network_precision", self.network_precision, f"one of {list(PRECISIONS)}")
        if not self.batch_window >= 0:
            raise ParameterError("batch_window", self.batch_window, "must be >= 0")
        if not self.diagnostics_period > 0:
            raise ParameterError("diagnostics_period", self.diagnostics_period, "must be > 0")
        if isinstance(self.bias_samples, bool) or not isinstance(self.bias_samples, int) or self.bias_samples < 1:
            raise ParameterError("bias_samples", self.bias_samples, "an integer >= 1")
        if not 0 < self.bias_contact_voltage < 3.3:
            raise ParameterError("bias_contact_voltage", self.bias_contact_voltage, "must be in (0, 3.3) V")
        return self

    def bundle_for(self, finger: str) -> str:
        return self.finger_bundles.get(finger) or self.model_bundle

    def bundles(self) -> dict[str, str]:
        """finger -> bundle path for every configured finger."""
        return {finger: self.bundle_for(finger) for finger in self.fingers}
