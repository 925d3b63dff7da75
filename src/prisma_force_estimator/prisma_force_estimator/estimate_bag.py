"""Run the inference pipeline over a recorded bag and write the wrench topics to a new bag."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from prisma_common.bag import BagWriter, read_bag, require_topics
from prisma_common.topics import TAXELS, WRENCH
from prisma_tactile_driver.ros_conversions import taxel_frame_from_msg

from .force_estimator_core import TaxelSample, WrenchPipeline
from .ros_conversions import MessageLookup, wrench_to_msg

TAXEL_TOPIC = TAXELS
WRENCH_TOPIC = WRENCH


@dataclass
class EstimateBagReport:
    taxel_messages: dict[str, int] = field(default_factory=dict)
    wrenches_written: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)

    def summary(self) -> str:
        rows = [f"{finger}: {self.taxel_messages.get(finger, 0)} taxel messages -> "
                f"{self.wrenches_written.get(finger, 0)} wrenches ({self.rejected.get(finger, 0)} rejected)"
                for finger in self.taxel_messages]
        return "\n".join(rows)


def estimate_bag(in_path: str | Path, out_path: str | Path, pipeline: WrenchPipeline, types: MessageLookup,
                 taxel_topic: str = TAXEL_TOPIC, wrench_topic: str = WRENCH_TOPIC,
                 storage: str = "mcap") -> EstimateBagReport:
    """Estimate a wrench for every taxel message of the pipeline's fingers in `in_path`.

    The output bag is written whole or not at all; an input bag without the taxel topic of one of
    the fingers raises MissingTopicsError (a ValueError) naming them, before anything is written."""
    # prisma_bringup depends on this package; importing its bag layer here, not at module level,
    # keeps the ROS package graph acyclic (colcon refuses cycles).
    topics = {taxel_topic.format(finger=f): f for f in pipeline.fingers}
    require_topics(in_path, topics)
    report = EstimateBagReport({f: 0 for f in pipeline.fingers}, {f: 0 for f in pipeline.fingers},
                               {f: 0 for f in pipeline.fingers})

    def write(writer: BagWriter, results) -> None:
        for finger, sample in results:
            writer.write(wrench_topic.format(finger=finger), wrench_to_msg(types, sample))
            report.wrenches_written[finger] += 1

    with BagWriter(out_path, storage=storage) as writer:
        for record in read_bag(in_path, topics=list(topics)):
            finger = topics[record.topic]
            frame = taxel_frame_from_msg(record.message)
            report.taxel_messages[finger] += 1
            write(writer, pipeline.add(TaxelSample(finger, frame.stamp_ns, frame.voltages,
                                                   str(record.message.header.frame_id))))
        write(writer, pipeline.flush())
    for finger in pipeline.fingers:
        report.rejected[finger] = pipeline.counts[finger].rejected
    return report
