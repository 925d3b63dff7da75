"""geometry_msgs.msg of the test stand-in: classes built from the rosbags typestore."""
from ros_standin.messages import export_package as _export

_export(globals(), 'geometry_msgs', 'msg')
