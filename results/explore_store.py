"""The rows of a design study and its resume store.

Each finished point becomes one table row (:func:`make_row`), written as one JSON record into the
resume store beside the output folder, so an interrupted study (or a lost worker) restarts from
the finished points (:func:`read_store`). A record is trusted only if it is exactly what
:func:`make_row` writes: a regular file named after its point id, a JSON object of known fields
with the right types, and (for a point of this study) the point's index and input values.
Anything else ends the run before it starts: a hand-edited or foreign file must never become a
row of the table.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import stat
from pathlib import Path
from typing import Any

from rpud_common import ParameterError, is_finite_number, write_json

from .explore_tasks import Failed
from .study import OUTPUTS, ROTOR_ERRORS, STAGES, Study

log = logging.getLogger(__name__)

__all__ = ["point_id", "make_row", "write_record", "MAX_RECORD_BYTES", "check_store", "read_store",
           "reset_store", "resume_store"]


def point_id(study: Study, index: int, point: dict, fingerprint: str | None = None) -> str:
    """``p<index>-<hash>``: the hash covers the point's values and the study's fingerprint, so a
    resumed study never picks up a record computed under other settings (``fingerprint``:
    :meth:`Study.fingerprint`, when already known)."""
    blob = json.dumps({"fp": fingerprint or study.fingerprint(), "point": point}, sort_keys=True)
    return f"p{index:05d}-{hashlib.sha256(blob.encode()).hexdigest()[:10]}"


def make_row(study: Study, index: int, point: dict, records: list, store: str | None = None) -> dict:
    """One table row from the stage records of a point (and write it to ``store`` if given)."""
    row: dict[str, Any] = {"point": index, "id": point_id(study, index, point)}
    row.update({f"in.{k}": v for k, v in point.items()})
    row["status"], row["error"], row["failed_stage"] = "ok", "", ""
    voltage = point.get("drive.voltage", study.settings.voltage)
    for rec in records:
        if isinstance(rec, Failed):
            row["status"], row["error"], row["failed_stage"] = "failed", rec.error, rec.stage
            break
        row.update(rec)
    if "tip_per_volt_m" in row:
        row["A0_unloaded_m"] = row["tip_per_volt_m"] * voltage
        row["power_w"] = row.pop("power_per_v2_w") * voltage ** 2
    if store is not None:
        write_record(Path(store), row)
    return row


def write_record(store: Path, row: dict) -> None:
    if store.is_dir():
        write_json(store / f"{row['id']}.json", row, nonfinite="null", provenance=False)



MAX_RECORD_BYTES = 1_000_000
"""Largest resume record read, bytes (a real one is about 2 kB)."""

_ID = re.compile(r"p(\d{5,9})-[0-9a-f]{10}\Z")
_TEXT_FIELDS = {"error": 1000, "failed_stage": 20, "impact_note": 2000, "rotor_note": 1000}
_NUMBER_FIELDS = (set(OUTPUTS) | {f"{o}_ci95" for o, v in OUTPUTS.items() if v[0] == "impact"}
                  | {f"{o}_error" for o in ROTOR_ERRORS}
                  | {f"{stage}_s" for stage in STAGES} | {"members", "stats_converged", "power_per_v2_w"})


def _bad_record(path: Path, value: Any, why: str) -> ParameterError:
    return ParameterError(f"resume record {path}", value, f"{why}; delete the file or run without --resume")


def _no_constant(name: str):
    raise ValueError(f"{name} is not written by a study (non-finite values are null)")


def check_store(store: Path) -> bool:
    """Whether the resume store exists; anything but a plain folder in its place is refused."""
    try:
        mode = os.lstat(store).st_mode
    except FileNotFoundError:
        return False
    except OSError as exc:
        raise ParameterError("resume store", str(store), f"cannot be read ({exc.strerror})") from None
    if not stat.S_ISDIR(mode):
        raise ParameterError("resume store", str(store), f"is a {_kind(mode)}, not a folder of resume records: "
                                                         "move it away")
    return True


def _kind(mode: int) -> str:
    kinds = ((stat.S_ISLNK, "link"), (stat.S_ISFIFO, "FIFO"), (stat.S_ISSOCK, "socket"), (stat.S_ISCHR, "device"),
             (stat.S_ISBLK, "device"), (stat.S_ISDIR, "folder"), (stat.S_ISREG, "file"))
    return next((name for test, name in kinds if test(mode)), "special file")


def _load_record(path: Path) -> Any:
    """Parse one record; only a regular file of bounded size is ever opened (a FIFO would block)."""
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode):
            raise _bad_record(path, _kind(st.st_mode), "is not a regular file")
        if st.st_size > MAX_RECORD_BYTES:
            raise _bad_record(path, f"{st.st_size} bytes", f"is larger than {MAX_RECORD_BYTES} bytes")
        # O_NONBLOCK and the second check: a file swapped for a FIFO after lstat neither blocks nor is read
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                raise _bad_record(path, "not a regular file", "is not a regular file")
            raw = f.read(MAX_RECORD_BYTES + 1)
    except OSError as exc:
        raise _bad_record(path, type(exc).__name__, f"cannot be read ({exc.strerror or exc})") from None
    try:
        return json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise _bad_record(path, raw[:40].decode("utf-8", "replace"), f"is not a JSON record ({exc})") from None


def _check_field(path: Path, key: str, value: Any) -> None:
    if key in ("id", "point", "status"):
        return
    if key in _TEXT_FIELDS:
        if not isinstance(value, str) or len(value) > _TEXT_FIELDS[key]:
            raise _bad_record(path, value, f"field {key!r} must be text of at most {_TEXT_FIELDS[key]} characters")
    elif key.startswith("in."):
        if not is_finite_number(value):
            raise _bad_record(path, value, f"field {key!r} must be a finite number")
    elif key in _NUMBER_FIELDS or key.startswith("tuned."):
        if value is not None and not is_finite_number(value):
            raise _bad_record(path, value, f"field {key!r} must be a finite number or null")
    else:
        raise _bad_record(path, key, "has an unknown field")


def _check_record(path: Path, rec: Any, study: Study) -> dict:
    """The record's structure and field types, as :func:`make_row` writes them."""
    if not isinstance(rec, dict):
        raise _bad_record(path, rec, "must be a JSON object (one table row)")
    rid = rec.get("id")
    match = _ID.match(rid) if isinstance(rid, str) else None
    if match is None or path.name != f"{rid}.json":
        raise _bad_record(path, rid, "field 'id' must be the point id the file is named after")
    point = rec.get("point")
    if isinstance(point, bool) or not isinstance(point, int) or point != int(match.group(1)):
        raise _bad_record(path, point, f"field 'point' must be the index {int(match.group(1))} of its id")
    status = rec.get("status")
    if not isinstance(status, str) or status not in ("ok", "failed"):
        raise _bad_record(path, status, "field 'status' must be 'ok' or 'failed'")
    for key, value in rec.items():
        _check_field(path, key, value)
    error, stage = rec.get("error"), rec.get("failed_stage")
    if status == "ok" and (error or stage):
        raise _bad_record(path, error or stage, "a point with status 'ok' has no error")
    if status == "failed" and (not error or stage not in study.stages):
        raise _bad_record(path, stage, f"a failed point names its error and its stage ({', '.join(study.stages)})")
    return rec


def _check_point_record(path: Path, rec: dict, study: Study, point: dict) -> None:
    """A record of one of this study's points: its inputs and, if ok, every output of the stages."""
    inputs = {k[3:]: v for k, v in rec.items() if k.startswith("in.")}
    if inputs != point:
        raise _bad_record(path, inputs, f"inputs must be those of point {rec['point']}: {point}")
    if rec["status"] == "ok":
        for o, (stage, _, _) in OUTPUTS.items():
            if stage in study.stages and o not in rec and not (o == "matched" and not study.settings.match):
                raise _bad_record(path, o, "a point with status 'ok' has every output of its stages")


def read_store(store: Path, study: Study, points: list[dict], ids: list[str]) -> dict[str, dict]:
    """The validated records of this study's points in the resume store, by point id.

    Records of other studies or settings (other ids) are checked, then left out; a record
    that is not what :func:`make_row` writes is a :class:`ParameterError` naming the file.
    """
    if not check_store(store):
        return {}
    index = {pid: i for i, pid in enumerate(ids)}
    done = {}
    for path in sorted(store.glob("p*.json")):
        rec = _check_record(path, _load_record(path), study)
        i = index.get(rec["id"])
        if i is None:
            log.info("resume record %s is of other settings or another study: not used", path)
            continue
        _check_point_record(path, rec, study, points[i])
        done[rec["id"]] = rec
    return done


# ------------------------------------------------------------------------------- plan


def resume_store(out: Path) -> Path:
    """The resume store of the study written to ``out``: a hidden folder beside it."""
    return out.parent / f".{out.name}.resume"


def reset_store(store: Path, resume: bool) -> None:
    """An empty store for a fresh run (``resume`` False), or the existing one kept."""
    if not resume and check_store(store):
        shutil.rmtree(store)
    store.mkdir(exist_ok=True)
