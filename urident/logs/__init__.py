"""Log format (CSV + YAML sidecar), crash-safe writer, and loaders for urident logs, ur_rtde
recorder CSVs, headerless foreign CSVs and rosbag2 bags. The format is documented in ``logs/README.md``."""

from .foreign import PRESETS, ColumnMap, ColumnMapError, parse_column_map
from .reader import describe_dropped, known_robot_names, load_log, parse_row_range
from .recording import Recording
from .rosbag import is_bag, load_bag, write_bag
from .schema import LOG_FIELDS, OPTIONAL_FIELDS, LogField, field_columns, sidecar_path
from .sidecar import read_sidecar, sha256_file
from .writer import LogWriter

__all__ = [
    "LOG_FIELDS",
    "OPTIONAL_FIELDS",
    "PRESETS",
    "ColumnMap",
    "ColumnMapError",
    "LogField",
    "LogWriter",
    "Recording",
    "describe_dropped",
    "field_columns",
    "is_bag",
    "load_bag",
    "known_robot_names",
    "load_log",
    "parse_column_map",
    "parse_row_range",
    "read_sidecar",
    "sha256_file",
    "sidecar_path",
    "write_bag",
]
