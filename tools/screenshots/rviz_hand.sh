#!/usr/bin/env bash
# RViz on the sim graph with the hand holding the ball after a pinch Grasp: the model moving with
# /joint_states, the fingers resting on the ball (tendon_stretch), the taxels coloured by the contact
# monitor's decision, the contact points and the normal-force arrows (config/hand.rviz), taken on a
# virtual X server:
#
#     PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh && source install/setup.bash
#     tools/screenshots/rviz_hand.sh [OUT.png]        # default docs/img/rviz_hand_pinch.png
#
# Run from the repository root with ROS 2 and the built workspace sourced. Needs Xvfb, xwd and
# ImageMagick's convert (apt-get install -y xvfb x11-apps imagemagick) and rviz2 (in the ROS tree;
# on a robot apt install ros-jazzy-rviz2); Mesa's software renderer draws it (LIBGL_ALWAYS_SOFTWARE=1).
# The graph and RViz run on a ROS domain and a display of their own; all of it is stopped at the end.
# The shipped configuration is used as it is: what the picture shows is what rviz:=true shows.
set -euo pipefail

out="${1:-docs/img/rviz_hand_pinch.png}"
source "$(dirname "${BASH_SOURCE[0]}")/session.sh"
require rviz_hand.sh "apt-get install -y xvfb x11-apps imagemagick; PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh;\
 source install/setup.bash" Xvfb xwd convert ros2 rviz2
config="$(ros2 pkg prefix prisma_bringup 2>/dev/null)/share/prisma_bringup/config/hand.rviz"
[ -f "$config" ] || { echo "rviz_hand.sh: no $config: colcon build, source install/setup.bash" >&2; exit 1; }

width=1280 height=800
export LIBGL_ALWAYS_SOFTWARE=1
screenshot_session rviz_hand.sh "$width" "$height" 5  # 5 s for the launch and rviz2 to stop

run_group ros2 launch prisma_bringup hand.launch.py sim:=true >"$work/hand.log" 2>&1
echo "rviz_hand.sh: hand.launch.py started; pinch Grasp..."
for attempt in 1 2 3; do
  if timeout 90 ros2 action send_goal /prisma/grasp prisma_msgs/action/Grasp "{grasp: pinch}" \
       >"$work/grasp.log" 2>&1 && grep -q "force_reached" "$work/grasp.log"; then
    break
  fi
  [ "$attempt" = 3 ] && { echo "rviz_hand.sh: the pinch Grasp did not reach its force" >&2; cat "$work/grasp.log" >&2; exit 1; }
  sleep 3
done

run_group rviz2 -d "$config" >"$work/rviz.log" 2>&1
echo "rviz_hand.sh: rviz2 started; waiting for it to draw..."
sleep 20  # start, description, TF and the first MarkerArrays under software rendering
if grep -E "\[(ERROR|WARN)\]|No transform|dropping message" "$work/rviz.log" >&2; then
  echo "rviz_hand.sh: rviz2 reported the problems above" >&2
  exit 1
fi
capture "$out" "${width}x$((height - 24))+0+0" 128
