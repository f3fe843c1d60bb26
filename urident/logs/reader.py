"""``load_log``: one loader for urident logs, ur_rtde recorder CSVs and headerless foreign CSVs."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Collection, Mapping

import numpy as np

from urident.errors import LogFormatError

from .foreign import PRESETS, ColumnMap, ColumnMapError, column_names, parse_column_map
from .recording import Recording, with_signal
from .rosbag import FORMAT_ROSBAG2, is_bag, load_bag
from .schema import (
    ALL_FIELDS,
    FIELDS_BY_ATTR,
    REQUIRED_ATTRS,
    STATUS_RUNNING,
    STATUS_UNKNOWN,
    sidecar_path,
)
from .sidecar import read_sidecar
from .validate import (
    DropReport,
    Issue,
    check_jumps,
    check_time,
    check_values,
    parse_cells,
    raise_first,
)

FORMAT_UREDENT = "urident"
FORMAT_UR_RTDE = "ur_rtde"
FORMAT_COLUMNS = "columns"

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_ROBOT = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_DROP_HINT = "pass drop_bad=True (--drop-bad) to drop bad rows"


def known_robot_names() -> list[str]:
    """Robot names with a robot file in ``urident/model/robots/`` (read from disk: urident.logs
    does not import urident.model)."""
    robots_dir = Path(__file__).resolve().parent.parent / "model" / "robots"
    return sorted(p.stem for p in robots_dir.glob("*.yaml"))


def parse_row_range(text: str) -> tuple[int, int]:
    """``"635-3510"`` or ``"635:3510"`` -> ``(635, 3510)``: 1-based inclusive data rows."""
    m = re.fullmatch(r"\s*(\d+)\s*[-:]\s*(\d+)\s*", str(text))
    if not m:
        raise LogFormatError(f"row range {text!r}: expected FIRST-LAST, e.g. 635-3510 (1-based)")
    return _check_range((int(m.group(1)), int(m.group(2))), f"row range {text!r}")


def _check_range(rows: Any, what: str) -> tuple[int, int]:
    try:
        first, last = (int(v) for v in rows)
    except (TypeError, ValueError):
        raise LogFormatError(f"{what}: expected (first, last), 1-based inclusive") from None
    if first < 1 or last < first:
        raise LogFormatError(f"{what}: need 1 <= first <= last, got {first}-{last}")
    return first, last


def load_log(
    path: str | Path,
    robot: str | None = None,
    rows: tuple[int, int] | str | None = None,
    drop_bad: bool = False,
    column_map: str | ColumnMap | Mapping[str, Any] | None = None,
    format: str | None = None,  # noqa: A002 - mirrors the --format option
    known_robots: Collection[str] | None = None,
    topic: str | None = None,
    effort: str | None = None,
    signal: str | None = None,
) -> Recording:
    """Load a log into a :class:`Recording`; any defect raises a one-line LogFormatError.

    Formats (auto-detected unless ``format`` says):

    * ``urident``: CSV with a ur_rtde-style header and a ``.yaml`` sidecar beside it;
    * ``ur_rtde``: a bare ``startFileRecording`` CSV (header, no sidecar): ``robot`` required;
    * headerless CSV through ``column_map`` (see :func:`parse_column_map`) or a preset
      ``format`` (``dynamic_calibration``, ``dynamic_calibration_19``): ``robot`` required.

    ``rows=(first, last)`` keeps data rows first..last, 1-based and inclusive, counted without the
    header line (for a headerless file they are the file's line numbers). Rows with identical
    content and timestamp are duplicates and removed (count in ``metadata["duplicates_removed"]``);
    in a ur_rtde recording, whose recorder thread can tear a row across two packages, every row
    repeating a timestamp is a duplicate (the first one is kept).

    Bad rows (wrong column count, non-numeric, NaN/inf, beyond the sane bound of their quantity,
    non-integer codes, time repeated with other values or going back, joint jumps, a truncated
    last line) are rejected with ``file:line: column NAME: ...``; with ``drop_bad=True`` they are
    dropped and reported in ``metadata["dropped"]`` (``count``, ``reasons``, ``lines``). The
    truncated last line of a log whose sidecar says ``running`` (crashed writer) is always
    dropped and reported.

    ``known_robots``: allowed robot names (default: the robot files of urident.model; the check
    is skipped when none is installed).

    A rosbag2 (a bag directory, or one ``.mcap`` / ``.db3`` file: :func:`is_bag`) is read by
    :func:`urident.logs.rosbag.load_bag` with ``topic`` (JointState, default ``/joint_states``)
    and ``effort`` (``current`` or ``torque``); ``rows`` then selects messages.

    ``signal``: which signal the torques come from (``current``, ``torque``, ``compensated``:
    :func:`urident.logs.recording.with_signal`); None lets the log's metadata decide.
    """
    return with_signal(_load(path, robot, rows, drop_bad, column_map, format, known_robots, topic, effort),
                       signal, path)


def _load(path, robot, rows, drop_bad, column_map, format, known_robots, topic, effort) -> Recording:  # noqa: A002
    if is_bag(path):
        if column_map is not None or format not in (None, FORMAT_ROSBAG2):
            raise LogFormatError(f"{path}: a rosbag2 bag takes no --format or --columns")
        if isinstance(rows, str):
            rows = parse_row_range(rows)
        rows = None if rows is None else _check_range(rows, f"{path}: rows")
        return load_bag(path, robot=robot, topic=topic, effort=effort, rows=rows,
                        drop_bad=drop_bad,
                        known_robots=known_robot_names() if known_robots is None else known_robots)
    if topic is not None or effort is not None:
        raise LogFormatError(f"{path}: --topic and --effort apply to rosbag2 bags only")
    return _Loader(path, robot, rows, drop_bad, column_map, format, known_robots).load()


class _Loader:
    def __init__(self, path, robot, rows, drop_bad, column_map, fmt, known_robots) -> None:
        self.path = Path(path)
        self.robot_arg = robot
        self.drop_bad = bool(drop_bad)
        self.fmt = fmt
        self.known_robots = known_robots
        self.column_map_arg = column_map
        if isinstance(rows, str):
            rows = parse_row_range(rows)
        self.rows = None if rows is None else _check_range(rows, f"{self.path}: rows")
        self.report = DropReport()
        self.duplicates = 0
        self.sample_count_mismatch: str | None = None

    # ------------------------------------------------------------------ top level
    def load(self) -> Recording:
        lines, final_newline = self._read_lines()
        header = self._header(lines[0])
        fmt, cmap, sidecar = self._resolve_format(header)
        # ur_rtde's recorder samples on its own thread while the receive thread updates the
        # state, so it writes torn rows: a timestamp repeated with other values. There (and only
        # there) keep the first row of each timestamp and count the rest as duplicates.
        self.torn_rows_allowed = fmt == FORMAT_UR_RTDE
        robot = self._resolve_robot(sidecar, fmt)
        status = (sidecar or {}).get("status") or STATUS_UNKNOWN

        first_data = 1 if header is not None else 0
        data = lines[first_data:]
        numbers = np.arange(first_data + 1, first_data + 1 + len(data), dtype=np.int64)
        if not data:
            raise LogFormatError(f"{self.path}: no data rows after the header")

        n_data_total = len(data)
        expected = (sidecar or {}).get("n_samples")
        if status != STATUS_RUNNING and expected is not None and expected != n_data_total:
            msg = (
                f"{self.path}: {n_data_total} data rows, but {sidecar_path(self.path).name} says "
                f"n_samples: {expected} (file cut or edited after the run?)"
            )
            if not self.drop_bad:
                raise LogFormatError(msg + "; " + _DROP_HINT)
            self.sample_count_mismatch = msg
        # a last line without newline is cut short when our writer or ur_rtde wrote the file
        if not final_newline:
            ncols_hint = len(header) if header is not None else None
            last_count = data[-1].count(",") + 1
            if fmt != FORMAT_COLUMNS or (ncols_hint is not None and last_count != ncols_hint):
                issue = Issue(int(numbers[-1]), None, "truncated", "truncated last line")
                if status == STATUS_RUNNING or self.drop_bad:
                    self.report.add([issue])
                    data, numbers = data[:-1], numbers[:-1]
                else:
                    raise_first(
                        [issue], self.path, "the writer was interrupted; " + _DROP_HINT
                    )

        if self.rows is not None:
            first, last = self.rows
            if last > n_data_total:
                raise LogFormatError(
                    f"{self.path}: rows {first}-{last} asked, the file has {n_data_total} data rows"
                )
            sel = (numbers - first_data >= first) & (numbers - first_data <= last)
            data = [ln for ln, s in zip(data, sel) if s]
            numbers = numbers[sel]
            self.report.issues = [
                i for i in self.report.issues if first <= i.line - first_data <= last
            ]
        if not data:
            raise LogFormatError(f"{self.path}: no data rows to load")

        ncols = self._ncols(header, cmap, data)
        arrays, kept_numbers = self._parse_and_check(data, numbers, ncols, cmap)
        return self._build(arrays, kept_numbers, fmt, cmap, sidecar, robot, status, header)

    # ------------------------------------------------------------------ reading
    def _read_lines(self) -> tuple[list[str], bool]:
        try:
            raw = self.path.read_bytes()
        except FileNotFoundError:
            raise LogFormatError(f"{self.path}: no such log file") from None
        except OSError as exc:
            raise LogFormatError(f"{self.path}: cannot read: {exc.strerror or exc}") from None
        if not raw.strip():
            raise LogFormatError(f"{self.path}: empty file")
        text = raw.decode("utf-8", errors="replace")  # bad bytes become non-numeric cells
        if text.startswith("\ufeff"):
            text = text[1:]
        text = text.replace("\r\n", "\n")
        final_newline = text.endswith("\n")
        lines = text.split("\n")
        if final_newline:
            lines.pop()
        while lines and not lines[-1].strip():  # trailing blank lines carry nothing
            lines.pop()
            final_newline = True
        if not lines:
            raise LogFormatError(f"{self.path}: empty file")
        return lines, final_newline

    def _header(self, line: str) -> list[str] | None:
        """Column names if ``line`` is a header (no cell is a number), else None."""
        cells = [c.strip() for c in line.split(",")]
        for c in cells:
            try:
                float(c)
                return None
            except ValueError:
                pass
        bad = [c for c in cells if not _NAME.match(c)]
        if bad:
            if self._explicit_map() is not None:
                return None  # a corrupt first data row of a headerless file
            raise LogFormatError(
                f"{self.path}:1: neither a header nor a data row: bad column name {bad[0][:40]!r}"
            )
        return cells

    def _explicit_map(self) -> ColumnMap | None:
        if self.column_map_arg is not None:
            return parse_column_map(self.column_map_arg)
        if self.fmt in PRESETS:
            return parse_column_map(self.fmt)
        return None

    def _resolve_format(
        self, header: list[str] | None
    ) -> tuple[str, ColumnMap, dict[str, Any] | None]:
        fmt = self.fmt
        known = (FORMAT_UREDENT, FORMAT_UR_RTDE, FORMAT_COLUMNS, None, *PRESETS)
        if fmt not in known:
            names = ", ".join(k for k in known if k)
            raise ColumnMapError(f"unknown log format {fmt!r} (known: {names})")
        if self.column_map_arg is not None and fmt in PRESETS:
            raise ColumnMapError("give either a column map (--columns) or a preset (--format)")
        explicit = self._explicit_map()
        side = sidecar_path(self.path)
        if explicit is not None:  # mapped by index; a header line, if any, is skipped
            return FORMAT_COLUMNS, explicit, None
        if header is None:
            raise LogFormatError(
                f"{self.path}:1: no header line; give a column map (--columns "
                f"'t=0,q=1:7,qd=7:13,current=13:19') or a preset (--format "
                f"{'|'.join(PRESETS)})"
            )
        cmap = self._header_map(header)
        if fmt == FORMAT_COLUMNS:
            raise ColumnMapError(f"{self.path}: format 'columns' needs a column map")
        if fmt == FORMAT_UREDENT or (fmt is None and side.exists()):
            if not side.exists():
                raise LogFormatError(f"{self.path}: no sidecar {side.name} beside the log")
            sidecar = read_sidecar(side)
            cols = sidecar.get("columns")
            if cols is not None and list(cols) != header:
                raise LogFormatError(
                    f"{self.path}:1: header does not match the columns listed in {side.name}"
                )
            return FORMAT_UREDENT, cmap, sidecar
        return FORMAT_UR_RTDE, cmap, None

    def _header_map(self, header: list[str]) -> ColumnMap:
        index: dict[str, int] = {}
        for i, name in enumerate(header):
            if name in index:
                raise LogFormatError(f"{self.path}:1: column {name} appears twice in the header")
            index[name] = i
        columns: dict[str, tuple[int, ...]] = {}
        for fld in ALL_FIELDS:
            present = [c for c in fld.columns if c in index]
            if not present:
                continue
            missing = [c for c in fld.columns if c not in index]
            if missing:
                raise LogFormatError(f"{self.path}:1: header lacks column {missing[0]}")
            columns[fld.attr] = tuple(index[c] for c in fld.columns)
        for attr in REQUIRED_ATTRS:
            if attr not in columns:
                fld = FIELDS_BY_ATTR[attr]
                raise LogFormatError(
                    f"{self.path}:1: header lacks column {fld.columns[0]} (required: timestamp, "
                    "actual_q_*, actual_qd_*, actual_current_*)"
                )
        return ColumnMap(columns, len(header), "header")

    def _resolve_robot(self, sidecar: dict[str, Any] | None, fmt: str) -> str:
        side_robot = (sidecar or {}).get("robot")
        arg = self.robot_arg
        if arg is not None and (not isinstance(arg, str) or not _ROBOT.match(arg)):
            raise LogFormatError(f"{self.path}: bad robot name {arg!r}")
        if side_robot is not None and arg is not None and side_robot != arg:
            raise LogFormatError(
                f"{self.path}: recorded on robot {side_robot!r} (sidecar), but robot {arg!r} given"
            )
        robot = arg or side_robot
        if robot is None:
            where = "its sidecar names no robot" if fmt == FORMAT_UREDENT else "it has no sidecar"
            raise LogFormatError(f"{self.path}: robot unknown ({where}); pass robot= (--robot)")
        if not _ROBOT.match(robot):
            raise LogFormatError(f"{sidecar_path(self.path)}: robot: is {robot!r}")
        known = self.known_robots if self.known_robots is not None else known_robot_names()
        if known and robot not in known:
            where = f"{sidecar_path(self.path)}: robot" if arg is None else "robot"
            raise LogFormatError(
                f"{self.path}: unknown robot {robot!r} ({where}); known: {', '.join(sorted(known))}"
            )
        return robot

    # ------------------------------------------------------------------ checking
    def _ncols(self, header: list[str] | None, cmap: ColumnMap, data: list[str]) -> int:
        if header is not None and cmap.spec == "header":
            return len(header)
        counts = np.fromiter((ln.count(",") + 1 for ln in data), dtype=np.int64, count=len(data))
        usual = int(np.bincount(counts).argmax())  # the usual count; rows with others are bad
        ncols = usual if cmap.ncols is None else cmap.ncols
        if usual != ncols and np.count_nonzero(counts == ncols) < len(data) / 2:
            fits = [k for k, (spec, _) in PRESETS.items() if _layout_ncols(spec) == usual]
            hint = f"; try --format {fits[0]}" if fits else ""
            raise ColumnMapError(
                f"{self.path}: rows have {usual} columns, column map {cmap.spec!r} expects "
                f"{ncols}{hint}"
            )
        if ncols < cmap.min_ncols:
            raise ColumnMapError(
                f"{self.path}: rows have {ncols} columns, column map {cmap.spec!r} needs "
                f"{cmap.min_ncols}"
            )
        return ncols

    def _parse_and_check(
        self, data: list[str], numbers: np.ndarray, ncols: int, cmap: ColumnMap
    ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        attrs = list(cmap.columns)
        used = [c for a in attrs for c in cmap.columns[a]]
        names_by_col = column_names(cmap) if cmap.spec != "header" else {}
        if cmap.spec == "header":
            for a in attrs:
                fld = FIELDS_BY_ATTR[a]
                for c, name in zip(cmap.columns[a], fld.columns):
                    names_by_col[c] = name
        names = [names_by_col[c] for c in used]
        bounds = np.concatenate(
            [np.full(len(cmap.columns[a]), FIELDS_BY_ATTR[a].bound) for a in attrs]
        )
        units = [FIELDS_BY_ATTR[a].unit for a in attrs for _ in cmap.columns[a]]
        integer = np.array(
            [FIELDS_BY_ATTR[a].dtype == "int" for a in attrs for _ in cmap.columns[a]], dtype=bool
        )

        values, nums, issues = parse_cells(data, numbers, ncols, used, names_by_col)
        self._handle(issues)
        ok, issues = check_values(values, nums, names, bounds, units, integer)
        self._handle(issues)
        values, nums = values[ok], nums[ok]

        t_col = used.index(cmap.columns["t"][0])
        keep, dup, issues = check_time(values[:, t_col], values, nums, names[t_col],
                                       torn_rows_allowed=self.torn_rows_allowed)
        self._handle(issues)
        self.duplicates += int(dup.sum())
        values, nums = values[keep], nums[keep]

        q_cols = [used.index(c) for c in cmap.columns["q"]]
        keep, issues = check_jumps(
            values[:, t_col],
            values[:, q_cols],
            nums,
            [names[i] for i in q_cols],
            self.drop_bad,
            self.path,
        )
        self._handle(issues)
        values, nums = values[keep], nums[keep]
        if values.shape[0] == 0:
            dropped = self.report.as_dict()
            raise LogFormatError(
                f"{self.path}: no valid rows left ({dropped['count']} dropped: "
                f"{_reasons_text(dropped['reasons'])}; first: {dropped['first']})"
            )

        arrays: dict[str, np.ndarray] = {}
        pos = 0
        for a in attrs:
            width = len(cmap.columns[a])
            block = values[:, pos : pos + width]
            arrays[a] = block[:, 0] if FIELDS_BY_ATTR[a].width == 1 else block
            pos += width
        return arrays, nums

    def _handle(self, issues: list[Issue]) -> None:
        if not issues:
            return
        if not self.drop_bad:
            raise_first(issues, self.path, _DROP_HINT)
        self.report.add(issues)

    # ------------------------------------------------------------------ result
    def _build(self, arrays, nums, fmt, cmap, sidecar, robot, status, header) -> Recording:
        metadata: dict[str, Any] = dict(sidecar or {})
        metadata["log_format"] = fmt
        if fmt == FORMAT_COLUMNS:
            metadata["column_map"] = cmap.spec
        metadata["status"] = status
        metadata["rows"] = list(self.rows) if self.rows else None
        metadata["first_line"] = int(nums[0])
        metadata["last_line"] = int(nums[-1])
        metadata["duplicates_removed"] = self.duplicates
        metadata["dropped"] = self.report.as_dict()
        if "tau" in arrays:  # a CSV's torque is RTDE actual_current_as_torque: UR compensates gravity
            metadata["torque_kind"] = "compensated"
        if self.sample_count_mismatch:
            metadata["dropped"]["sample_count_mismatch"] = self.sample_count_mismatch

        if fmt == FORMAT_UR_RTDE:
            # ur_rtde's recorder samples the latest state on its own clock: next to the repeated
            # rows (dropped above) it skips single controller samples; each is bridged
            from .gaps import bridge_single_misses, controller_period

            period = controller_period(arrays["t"])
            ints = frozenset(a for a in arrays if FIELDS_BY_ATTR[a].dtype == "int")
            arrays, bridged = bridge_single_misses(arrays, period, ints)
            metadata["rate_hz"] = None if period is None else 1.0 / period
            metadata["bridged"] = bridged
            if bridged or self.duplicates:
                metadata.setdefault("notes", []).append(
                    f"{self.path}: ur_rtde recording: {self.duplicates} repeated row(s) dropped, "
                    f"{bridged} single missing period(s) bridged (each sample the mean of its two "
                    "neighbours, whose intervals are on time); longer losses stay gaps")
        rate = (sidecar or {}).get("rate_hz") or metadata.get("rate_hz")
        if rate is None and arrays["t"].shape[0] > 1:
            rate = float(f"{1.0 / np.median(np.diff(arrays['t'])):.6g}")
        if header is not None and cmap.spec == "header":
            used = {c for cols in cmap.columns.values() for c in cols}
            metadata["ignored_columns"] = [h for i, h in enumerate(header) if i not in used]
        return Recording(
            source=self.path,
            robot=robot,
            rate_hz=None if rate is None else float(rate),
            metadata=metadata,
            **arrays,
        )


def _layout_ncols(spec: str) -> int | None:
    return parse_column_map(spec).ncols


def _reasons_text(reasons: Mapping[str, int]) -> str:
    return ", ".join(f"{n} {r}" for r, n in reasons.items())


def describe_dropped(recording: Recording) -> str | None:
    """One line for the CLI: how many rows were dropped and why, or None when none were."""
    dropped = recording.metadata.get("dropped") or {}
    parts = []
    if dropped.get("count"):
        parts.append(
            f"{recording.source}: dropped {dropped['count']} bad row(s): "
            f"{_reasons_text(dropped['reasons'])}; first: {dropped['first']}"
        )
    if dropped.get("sample_count_mismatch"):
        parts.append(dropped["sample_count_mismatch"])
    return "; ".join(parts) or None
