#!/usr/bin/env bash
# rqt_reconfigure on the manipulation node, k with its slider (the FloatingPointRange its
# ParameterDescriptor advertises), taken on a virtual X server:
#
#     PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh && source install/setup.bash
#     tools/screenshots/rqt_reconfigure.sh [OUT.png]        # default docs/img/rqt_reconfigure_k.png
#
# Run from the repository root with ROS 2 and the built workspace sourced. Needs Xvfb, xdotool, xwd
# and ImageMagick's convert (apt-get install -y xvfb xdotool x11-apps imagemagick), PyQt5 and
# rqt_reconfigure (in the ROS tree; on a robot: apt install ros-jazzy-rqt-reconfigure). The node and
# rqt run on a ROS domain of their own and a display of their own; both are stopped at the end.
set -euo pipefail

out="${1:-docs/img/rqt_reconfigure_k.png}"
source "$(dirname "${BASH_SOURCE[0]}")/session.sh"
require rqt_reconfigure.sh "apt-get install -y xvfb xdotool x11-apps imagemagick; PRISMA_ROS_GUI=1 source \
../shared/ros2/setup.sh; source install/setup.bash" Xvfb xdotool xwd convert ros2 python:PyQt5 python:rqt_reconfigure
[ -f config/manipulation.yaml ] || { echo "rqt_reconfigure.sh: run it from the repository root" >&2; exit 1; }

width=1000 height=1180 crop_height=872
screenshot_session rqt_reconfigure.sh "$width" "$height"

run_group ros2 run prisma_manipulation manipulation --ros-args --params-file config/manipulation.yaml \
  >"$work/manipulation.log" 2>&1
# rqt_reconfigure selects the nodes named on its command line once it discovers them
run_group ros2 run rqt_reconfigure rqt_reconfigure /manipulation >"$work/rqt.log" 2>&1

window=$(timeout 60 xdotool search --sync --onlyvisible --name "rqt_reconfigure") \
  || { echo "rqt_reconfigure.sh: no rqt_reconfigure window within 60 s" >&2; cat "$work/rqt.log" >&2; exit 1; }
xdotool windowmove "$window" 0 0 windowsize "$window" "$width" "$height"
sleep 8  # discovery, the node's selection and its parameter editors
# the parameter pane; below it rqt's empty message pane
capture "$out" "${width}x${crop_height}+0+0" 64
