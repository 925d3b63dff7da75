"""force_estimator node parameters: defaults and their specs (description, unit, bounds, read-only),
validation naming the bad parameter and value, and the per-finger bundle choice. The node only
copies ROS parameters in.

Nothing is live: the networks, their threads and precision, the batching and the topics are set up
at start (a new bundle means loading and checking a network, which is what a restart does).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from prisma_common.hand import FINGERS
from prisma_common.parameters import ParameterError, ParameterSpec, Params, check_fingers, parameter

from .bias import DEFAULT_CONTACT_VOLTAGE, DEFAULT_SAMPLES
from .bundle import DEFAULT_BUNDLE, DEFAULT_PRECISION, PRECISIONS

__all__ = ["ForceEstimatorConfig", "ParameterError", "FINGERS", "OVERRIDE_PREFIX"]
OVERRIDE_PREFIX = "finger_bundles."


@dataclass
class ForceEstimatorConfig(Params):
    model_bundle: str = parameter(DEFAULT_BUNDLE, "model bundle directory (model.pt + metadata.json) for every "
                                                  "finger without an override; a relative path is looked up in the "
                                                  "working directory, the workspace and share/prisma_bringup")
    # finger -> bundle directory; "" = use model_bundle. ROS parameters finger_bundles.<finger>.
    finger_bundles: dict[str, str] = parameter({f: "" for f in FINGERS}, "model bundle directory for the {finger}; "
                                                                          "'' = model_bundle")
    # the physical hand's directory (hand_directory.py): its bundles.yaml beats model_bundle, its
    # force_bias.yaml is applied at start and rewritten by ~/bias
    hand_config: str = parameter("", "per-hand directory (bundles.yaml, force_bias.yaml); '' = none: the shipped "
                                     "config only, ~/bias not saved")
    fingers: list[str] = parameter(list(FINGERS), "fingers whose taxels are estimated",
                                   rules=f"distinct names of {', '.join(FINGERS)}")
    frame_id_format: str = parameter("", "header.frame_id of the wrenches: '' = the input TaxelArray's, else a "
                                         "pattern such as prisma_{finger}_pad",
                                     rules="'' or a str.format pattern whose only field is {finger}")
    torch_threads: int = parameter(1, "intra-op threads of the network (process-wide)", bounds=(1, 64))
    # "float16": float16 weights on the network's dense-chain form (CNN2; other networks run in
    # float32); "float32": the bundle's TorchScript network as it is (docs/force_estimation.md)
    network_precision: str = parameter(DEFAULT_PRECISION, "float16: CNN2's dense form with float16 weights (other "
                                                          "networks run float32); float32: the bundle's network",
                                       choices=PRECISIONS)
    batch_window: float = parameter(0.005, "samples whose stamps lie this close form one batch (one scan)",
                                    unit="s", bounds=(0.0, 0.1))
    diagnostics_period: float = parameter(1.0, "time between /diagnostics messages", unit="s", bounds=(0.0, 60.0),
                                          open_low=True)
    bias_samples: int = parameter(DEFAULT_SAMPLES, "~/bias: each finger's no-load offset is the mean of its last "
                                                   "this many estimates", bounds=(1, 10_000))
    bias_contact_voltage: float = parameter(DEFAULT_CONTACT_VOLTAGE, "~/bias is refused while a pad's taxel mean "
                                                                     "voltage reaches this (the finger is touched)",
                                            unit="V", bounds=(0.0, 3.3), open_low=True, open_high=True)

    @classmethod
    def parameter_specs(cls) -> dict[str, ParameterSpec]:
        """finger_bundles is one ROS parameter per finger, finger_bundles.<finger>."""
        specs: dict[str, ParameterSpec] = {}
        for name, spec in super().parameter_specs().items():
            if name == "finger_bundles":
                for finger in FINGERS:
                    specs[OVERRIDE_PREFIX + finger] = replace(spec, description=spec.description.format(finger=finger))
            else:
                specs[name] = spec
        return specs

    def as_parameters(self) -> dict[str, Any]:
        """Flat ROS parameter names and values (overrides as finger_bundles.<finger>)."""
        params: dict[str, Any] = {}
        for name, value in super().as_parameters().items():
            if name == "finger_bundles":
                params.update({OVERRIDE_PREFIX + finger: self.finger_bundles.get(finger, "") for finger in FINGERS})
            else:
                params[name] = value
        return params

    @classmethod
    def _from_flat(cls, values: dict[str, Any]) -> ForceEstimatorConfig:
        bundles = {name[len(OVERRIDE_PREFIX):]: value for name, value in values.items()
                   if name.startswith(OVERRIDE_PREFIX)}
        config = cls(**{name: value for name, value in values.items() if not name.startswith(OVERRIDE_PREFIX)})
        config.finger_bundles.update(bundles)
        return config

    def check_rules(self) -> None:
        if not self.model_bundle:
            raise ParameterError("model_bundle", self.model_bundle, "a bundle directory path")
        for finger, path in self.finger_bundles.items():
            if finger not in FINGERS:
                raise ParameterError(OVERRIDE_PREFIX + finger, path, f"{finger!r} is not one of {FINGERS}")
        check_fingers(self.fingers)
        try:
            self.frame_id_format.format(finger="thumb")
        except (KeyError, IndexError, ValueError, AttributeError) as exc:
            raise ParameterError("frame_id_format", self.frame_id_format,
                                 f"'' or a str.format pattern whose only field is {{finger}} ({exc})") from None

    def bundle_for(self, finger: str) -> str:
        return self.finger_bundles.get(finger) or self.model_bundle

    def bundles(self) -> dict[str, str]:
        """finger -> bundle path for every configured finger."""
        return {finger: self.bundle_for(finger) for finger in self.fingers}
