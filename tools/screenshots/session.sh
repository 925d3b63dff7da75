# Sourced by the screenshot scripts (bash): what each takes its picture in, set up once here.
#
#     require NAME HINT ITEM...                         # exit naming each ITEM missing (python:MODULE)
#     screenshot_session NAME WIDTH HEIGHT [GRACE_S]   # a work folder, a ROS domain, a display of its own
#     run_group COMMAND...                              # start COMMAND in a process group stopped at exit
#     capture OUT CROP COLORS                           # the display into OUT.png, whole or not at all
#
# At exit every group started here gets SIGINT, GRACE_S seconds (default 1) to shut down, then
# SIGKILL (`ros2 run` leaves its node running when only it is stopped); the ROS daemon of the
# domain is stopped and the work folder removed.

require() {
  local name=$1 hint=$2 item
  local missing=()
  shift 2
  for item in "$@"; do
    case $item in
      python:*) python3 -c "import ${item#python:}" 2>/dev/null || missing+=("${item#python:}") ;;
      *) command -v "$item" >/dev/null || missing+=("$item") ;;
    esac
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    echo "$name: missing ${missing[*]} ($hint)" >&2
    exit 1
  fi
}

screenshot_session() {
  session_name=$1
  session_grace_s=${4:-1}
  export ROS_DOMAIN_ID=$((101 + $$ % 130))  # this script's graph only
  export RCUTILS_COLORIZED_OUTPUT=0
  work=$(mktemp -d)
  session_groups=()
  trap _session_cleanup EXIT
  # Xvfb picks a free display number and writes it once it accepts clients
  run_group Xvfb -displayfd 1 -screen 0 "${2}x${3}x24" -nolisten tcp >"$work/display" 2>/dev/null
  for _ in $(seq 100); do [ -s "$work/display" ] && break; sleep 0.1; done
  [ -s "$work/display" ] || { echo "$session_name: Xvfb did not start" >&2; exit 1; }
  export DISPLAY=":$(head -n1 "$work/display")"
}

run_group() {
  setsid "$@" &
  session_groups+=($!)
}

_session_cleanup() {
  for pgid in "${session_groups[@]}"; do kill -INT -- "-$pgid" 2>/dev/null || true; done
  sleep "$session_grace_s"
  for pgid in "${session_groups[@]}"; do kill -KILL -- "-$pgid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  ros2 daemon stop >/dev/null 2>&1 || true
  rm -rf "$work"
}

capture() {
  mkdir -p "$(dirname "$1")"
  local tmp="$1.partial-$$.png"
  xwd -root -silent | convert xwd:- -crop "$2" +repage -colors "$3" "$tmp"
  mv "$tmp" "$1"
  echo "$session_name: wrote $1"
}
