"""/diagnostics content of the force estimator: per-finger sample counters and bias offset."""
from __future__ import annotations

from collections.abc import Mapping

from prisma_common.diagnostics import OK, WARN, DiagnosticStatusData

from .force_estimator_core import WrenchPipeline


def pipeline_diagnostics(pipeline: WrenchPipeline, name: str, bundles: Mapping[str, str]) -> list[DiagnosticStatusData]:
    """One status per finger: WARN once any sample was rejected (non-finite voltages); `bias` is the
    offset subtracted (fx fy fz in N, tx ty tz in N*m) or none."""
    statuses = []
    for finger, counts in pipeline.counts.items():
        estimator = pipeline.estimators[finger]
        level = WARN if counts.rejected else OK
        message = (f"{counts.rejected} sample(s) rejected: non-finite voltages" if counts.rejected
                   else "ok")
        statuses.append(DiagnosticStatusData(
            name=f"{name}: {finger}",
            level=level,
            message=message,
            hardware_id=bundles.get(finger, ""),
            values={"received": str(counts.received), "estimated": str(counts.estimated),
                    "rejected": str(counts.rejected), "model_kind": estimator.model_kind,
                    "bias": pipeline.bias.describe(finger) if pipeline.bias is not None else "none"},
        ))
    return statuses
