"""Where readings go: stdout and a live status line, CSV and JSONL files (``files``), MCAP logs
(``mcap_log``, the 'mcap' extra), ROS 2 topics over Cyclone DDS (``ros2_topic``, the 'ros2'
extra) or to ROS 2 nodes on rmw_zenoh through a Zenoh router (``zenoh_topic``, the 'zenoh'
extra), a live Foxglove view (``foxglove_live``, the 'foxglove' extra).

Every writer has ``write(reading)`` and ``close()`` and flushes per reading, so whatever was
written survives a crash. Only the file writers load with this package; the others import
their libraries when first used.
"""

from .files import FIELDS, CsvWriter, JsonlWriter, StdoutWriter, format_reading

__all__ = ["FIELDS", "CsvWriter", "JsonlWriter", "StdoutWriter", "format_reading"]
