"""rqt_plot, the real one: its own plot widget (rqt_plot.plot_widget.PlotWidget with the DataPlot
the rqt plugin gives it) plots /prisma/thumb/contact/threshold and
/prisma/thumb/contact/voltages[3] from the live sim graph (`hand.launch.py sim:=true`), rendered
offscreen (Qt's offscreen platform, no display needed).

rqt_plot needs PyQt5: `PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh` installs it (on a robot,
apt's python3-pyqt5 comes with rqt_plot). Without it this module skips, except under
PRISMA_ROS_GUI=1 (what CI sets), where a missing PyQt5 is an error.

docs/visualization.md's screenshot (docs/img/rqt_plot_thumb_threshold.png) is the real rqt_plot on
an X server while the graph runs a horizontal manipulation; the procedure is in that page's "Taxel
thresholds in rqt" section.
"""
from __future__ import annotations

import bisect
import math
import os
import statistics
import time

import pytest

from prisma_testing.node_process import ros2_launch, stop_process
from prisma_testing.ros_harness import require_ros

require_ros()

THRESHOLD = "/prisma/thumb/contact/threshold"
TAXEL_3 = "/prisma/thumb/contact/voltages[3]"
VREF = 3.3  # taxel voltages are 12-bit counts of a 3.3 V reference


def _import_rqt_plot():
    """rqt_plot's widget and data plot, or the import error. Importing rqt_plot's matplotlib
    backend switches matplotlib to Qt5Agg; the previous backend is put back so that later tests'
    plots stay off-screen."""
    import matplotlib

    try:
        before = matplotlib.get_backend(auto_select=False)
    except TypeError:  # matplotlib < 3.9
        before = matplotlib.get_backend()
    try:
        from python_qt_binding.QtGui import QColor
        from python_qt_binding.QtWidgets import QApplication
        from rqt_plot.data_plot import DataPlot
        from rqt_plot.plot_widget import PlotWidget
    except ImportError as exc:
        return None, f"{exc}"
    finally:
        matplotlib.use(before or "Agg")
    return (QApplication, QColor, DataPlot, PlotWidget), None


_RQT, _RQT_ERROR = _import_rqt_plot()
if _RQT_ERROR is not None:
    if os.environ.get("PRISMA_ROS_GUI") == "1":
        raise RuntimeError(f"PRISMA_ROS_GUI=1 but rqt_plot cannot be imported: {_RQT_ERROR}")
    pytest.skip(f"rqt_plot needs PyQt5: PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh [{_RQT_ERROR}]",
                allow_module_level=True)
QApplication, QColor, DataPlot, PlotWidget = _RQT

from prisma_msgs.msg import ContactState  # noqa: E402


def colour_distance(a, b) -> int:
    return abs(a.red() - b.red()) + abs(a.green() - b.green()) + abs(a.blue() - b.blue())


def plot_x(msg, start_time: float) -> float:
    """The x of a message in rqt_plot: its header stamp in seconds after the widget started
    (computed as rqt_plot.rosplot.ROSData does, so the floats compare exactly)."""
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 10**-9 - start_time


def probe_gap_around(probe_xs: list[float], x: float) -> float:
    """The gap between the probe's messages on either side of `x` (inf at the ends)."""
    after = bisect.bisect_left(probe_xs, x)
    if after == 0 or after == len(probe_xs):
        return math.inf
    return probe_xs[after] - probe_xs[after - 1]


def test_rqt_plot_widget_plots_threshold_against_taxel_3(ros):
    app = QApplication.instance() or QApplication(["rqt_plot", "-platform", "offscreen"])
    hand = ros2_launch("prisma_bringup", "hand.launch.py", "sim:=true")
    widget = None
    try:
        contacts = ros.collect(ContactState, "/prisma/thumb/contact")
        # rqt_plot resolves a field path against the topics the graph has: start it once they flow
        assert ros.spin_until(lambda: len(contacts) > 10, 120.0), hand.output

        # what rqt_plot's plugin (rqt_plot/plot.py) does with `rqt_plot THRESHOLD TAXEL_3`
        widget = PlotWidget(ros.probe, initial_topics=[THRESHOLD, TAXEL_3])
        data_plot = DataPlot(widget)
        data_plot.set_autoscale(x=False)
        data_plot.set_autoscale(y=DataPlot.SCALE_EXTEND | DataPlot.SCALE_VISIBLE)
        data_plot.set_xlim([0, 10.0])
        widget.switch_data_plot_widget(data_plot)
        widget.resize(800, 500)
        widget.show()
        assert set(widget._rosdata) == {THRESHOLD, TAXEL_3}, "rqt_plot refused a field path"
        first = len(contacts)

        painted = [0.0]

        def filled() -> bool:
            # the widget's 40 ms update timer moves the samples into the curves and redraws them; its
            # subscriptions are taken by the spins between. Painted at each spin, a busy machine left
            # rqt_plot's depth-10 subscriptions 70 points in 60 s: every tenth of a second here, as
            # rqt's own executor thread would take them beside the Qt loop
            if time.monotonic() - painted[0] >= 0.1:
                app.processEvents()
                painted[0] = time.monotonic()
            return all(len(data_plot._curves[name]["y"]) >= 100 for name in (THRESHOLD, TAXEL_3))

        assert ros.spin_until(filled, 60.0), {n: len(data_plot._curves[n]["y"]) for n in (THRESHOLD, TAXEL_3)}
        curves = {name: (data_plot._curves[name]["x"].copy(), data_plot._curves[name]["y"].copy())
                  for name in (THRESHOLD, TAXEL_3)}
        # the probe's own copy of the last plotted messages: rqt_plot's subscription keeps the newest
        # 10 and this one all of them, so on a busy machine this one is seconds behind rqt_plot's
        newest = max(float(xs.max()) for xs, _ in curves.values())
        assert ros.spin_until(lambda: plot_x(contacts[-1], widget._start_time) >= newest, 60.0), (
            f"the probe took /prisma/thumb/contact up to x = {plot_x(contacts[-1], widget._start_time):.3f}, "
            f"rqt_plot's newest point is at {newest:.3f}")
        # the view a user sets in rqt_plot's axis settings: the samples' span with a margin. Its
        # autoscale pads nothing, so the lower curve lay on the axes' border, a clipped line of
        # 29-70 pixels over the second or so of samples in the 10 s window
        every_y = [y for _, ys in curves.values() for y in ys]
        margin = 0.1 * (max(every_y) - min(every_y) or 0.1)
        data_plot.set_autoscale(y=0)
        data_plot.set_xlim([min(float(xs.min()) for xs, _ in curves.values()), newest])
        data_plot.set_ylim([min(every_y) - margin, max(every_y) + margin])
        data_plot.redraw()
        app.processEvents()
        lines = {name: line for name, line in data_plot._data_plot_widget._curves.items()}
        drawn = {name: len(line.get_xdata()) for name, line in lines.items()}
        image = widget.grab().toImage()
    finally:
        if widget is not None:
            widget.clean_up_subscribers()
            widget.close()
        stop_process(hand)

    assert len(contacts) - first >= 100
    # every plotted point is the field of a ContactState the graph published, at that message's stamp
    by_x = {plot_x(m, widget._start_time): m for m in contacts}
    probe_xs = sorted(by_x)
    period = statistics.median(b - a for a, b in zip(probe_xs, probe_xs[1:]))  # the stream's period
    for name, field in ((THRESHOLD, lambda m: m.threshold), (TAXEL_3, lambda m: m.voltages[3])):
        xs, ys = curves[name]
        assert len(xs) == len(ys) >= 100
        not_in_probe = [x for x in xs if x not in by_x]
        for x in not_in_probe:
            # beside the load harness the probe's own reliable depth-10 stream once lacked a sample
            # rqt_plot's subscription had: allowed only where the probe's stamps show that hole
            assert probe_gap_around(probe_xs, x) > 1.5 * period, (
                f"{name}: a point at x = {x} that no /prisma/thumb/contact message has, and the probe "
                f"received the messages on both sides of it")
        print(f"{name}: {len(xs)} points, {len(not_in_probe)} at a sample the probe lost")
        assert len(not_in_probe) <= len(xs) // 50, (name, not_in_probe)
        for x, y in zip(xs, ys):
            if x in by_x:
                assert y == float(field(by_x[x])), name
        assert 0.0 < ys.min() and ys.max() < VREF, (name, ys.min(), ys.max())
    # the threshold is K x the mean taxel voltage (k = 0.8 in config/manipulation.yaml); nothing
    # touches the thumb, so taxel 3 sits above it (safe) at every sample
    for x, v3 in zip(*curves[TAXEL_3]):
        msg = by_x[x]
        assert msg.threshold == pytest.approx(msg.k * msg.mean_voltage, rel=1e-5)
        assert msg.k == pytest.approx(0.8) and v3 > msg.threshold and msg.safe[3]
    # both curves were drawn: the matplotlib lines hold the samples, the widget shows their colours
    assert drawn[THRESHOLD] >= 100 and drawn[TAXEL_3] >= 100, drawn
    for name, line in lines.items():
        colour = QColor(line.get_color())
        near = sum(1 for x in range(image.width()) for y in range(image.height())
                   if colour_distance(image.pixelColor(x, y), colour) < 60)
        assert near > 50, f"{name}: {near} pixels of its colour {colour.name()} on screen"
