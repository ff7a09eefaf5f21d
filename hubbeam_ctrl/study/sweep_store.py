"""A sweep's study folder on disk: ``results.csv`` (appended as cases finish, repaired on
resume), ``study.json`` (the spec the rows belong to) and the folder's lock.

:func:`hubbeam_ctrl.study.sweep.sweep` runs the cases and hands their rows here; the names are
importable from :mod:`hubbeam_ctrl.study.sweep` too.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import sys
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError, write_error
from hubbeam_ctrl.core.fileio import atomic_write_text, output_folder
from hubbeam_ctrl.study.report import CSV_FIELDS
from hubbeam_ctrl.study.spec import StudySpec

__all__ = ["result_columns", "read_results"]

_RESULTS = "results.csv"
_STUDY = "study.json"


def result_columns(spec: StudySpec) -> list:
    """Columns of ``results.csv`` (and of the returned DataFrame), in order.

    Parameters
    ----------
    spec : StudySpec
        The study (its factors become columns).
    """
    metrics = [c for c in CSV_FIELDS if c not in ("controller", "plant", "scenario", "wall_s", "message")]
    head = ["case", *spec.factors, "controller", "plant", "scenario", "verdict"]
    return head + [c for c in metrics if c not in head] + ["error", "message", "setup_s", "wall_s", "sim_wall_s"]


def _csv_text(rows: list, columns: list, header: bool = False) -> str:
    """CSV lines of ``rows`` (floats as ``repr``: they read back bit-exact; None as empty)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    if header:
        writer.writeheader()
    for r in rows:
        writer.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in columns})
    return buf.getvalue()


class _ResultsFile:
    """``results.csv`` with a fixed header; each batch is appended with one write."""

    def __init__(self, path: Path, columns: list):
        self.path, self.columns = path, columns
        if not path.exists():
            atomic_write_text(path, ",".join(columns) + "\n")
        with open(path, "rb+") as fh:      # drop a line cut short by a kill
            data = fh.read()
            if data and not data.endswith(b"\n"):
                fh.truncate(data.rfind(b"\n") + 1)
        header = path.read_text().split("\n", 1)[0].split(",")
        if header != columns:
            raise ParameterError(f"out: {path} has other columns than this version writes; "
                                 "choose another --out")

    def append(self, rows: list) -> None:
        data = _csv_text(rows, self.columns).encode()
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
            try:
                size = os.fstat(fd).st_size
                try:
                    written = os.write(fd, data)
                    if written != len(data):
                        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                    os.fsync(fd)
                except OSError:
                    os.ftruncate(fd, size)          # whole batches only: drop a part-written one
                    raise
            finally:
                os.close(fd)
        except OSError as exc:
            raise write_error(exc, f"out: cannot write {self.path}") from None


_LOCK = ".hubbeam-sweep.lock"


class _StudyFolder:
    """The ``--out`` folder of a sweep, held for the length of the run.

    Taking it: an exclusive lock (``fcntl.flock`` on :data:`_LOCK` in the folder; a second
    sweep on the same folder is refused, it cannot append too), ``study.json`` checked
    against the spec (damaged: refused in one line), and on ``resume`` ``results.csv``
    repaired (:func:`_repair_results`). A folder this call created is removed again if the
    run fails before any row reached ``results.csv``.
    """

    def __init__(self, out_dir, spec: StudySpec, resume: bool):
        self.out = output_folder(out_dir, create=False)
        self.spec, self.resume = spec, resume
        self.created = not self.out.exists()
        self._fd = None

    def __enter__(self):
        try:
            self.out.mkdir(exist_ok=True)
        except OSError as exc:
            raise write_error(exc, f"out: cannot create {self.out}") from None
        try:
            self._lock()
            self.done = _check_study_folder(self.out, self.spec, self.resume)
            self.results = _ResultsFile(self.out / _RESULTS, result_columns(self.spec))
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        return self

    def _lock(self) -> None:
        import fcntl
        try:
            self._fd = os.open(self.out / _LOCK, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise write_error(exc, f"out: cannot create the lock file in {self.out}") from None
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._fd)
            self._fd = None
            raise ParameterError(f"out: another sweep is running in {self.out} (it holds {_LOCK}); "
                                 "wait for it to finish or choose another --out") from None

    def __exit__(self, exc_type, *_):
        if self._fd is None:
            return False                        # the lock is another sweep's: its folder is left alone
        if exc_type is not None and self.created and not _has_rows(self.out / _RESULTS):
            import shutil
            shutil.rmtree(self.out, ignore_errors=True)   # nothing finished: leave no empty --out
        os.close(self._fd)                      # releases the lock
        self._fd = None
        return False


def _has_rows(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            return fh.read(1 << 16).count(b"\n") > 1
    except OSError:
        return False


def _read_study_json(meta: Path):
    """The ``spec_hash`` of ``study.json``, or a one-line refusal naming what is wrong."""
    def damaged(reason):
        return ParameterError(f"out: {meta} is damaged ({reason}); it says which study the folder holds: "
                              "choose another --out")
    if not meta.is_file():
        raise damaged("not a regular file")
    try:
        if meta.stat().st_size > 64_000_000:
            raise OSError(errno.EFBIG, "larger than 64 MB")
        doc = json.loads(meta.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise damaged(f"cannot be read: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise damaged(f"not JSON: {' '.join(str(exc).split())[:80]}") from None
    stored = doc.get("spec_hash") if isinstance(doc, dict) else None
    if not isinstance(stored, str) or not stored:
        raise damaged("no spec_hash")
    return stored


def _check_study_folder(out: Path, spec: StudySpec, resume: bool) -> set:
    """Check ``study.json`` against ``spec``, repair ``results.csv`` on resume, write
    ``study.json``; returns the cases already finished."""
    meta, results = out / _STUDY, out / _RESULTS
    done = set()
    if meta.exists() or meta.is_symlink():
        if results.exists():
            stored = _read_study_json(meta)
            if stored != spec.hash():
                raise ParameterError(f"out: {out} holds results of a different study spec (hash {stored[:12]}, "
                                     f"this spec {spec.hash()[:12]}); choose another --out")
            if not resume:
                raise ParameterError(f"out: {out} already holds results of this study; pass --resume to "
                                     "finish it, or choose another --out")
            done = _repair_results(results, spec)
    elif results.exists():
        raise ParameterError(f"out: {out} holds a {_RESULTS} of an unknown study; choose another --out")
    atomic_write_text(meta, json.dumps({"spec_hash": spec.hash(), "n_cases": len(spec.cases()),
                                        "spec": spec.to_dict()}, indent=2, default=str) + "\n")
    return done


def _repair_results(path: Path, spec: StudySpec) -> set:
    """Keep the rows of ``results.csv`` that belong to this study, once each; return the
    cases finished (a row for every controller).

    Dropped: a line cut short, rows of cases not in the plan (``case = 999``) or of other
    controllers, repeated (case, controller) rows (the first is kept) and the rows of a case
    that lacks a controller (it is run again). The file is rewritten (atomically) only if
    something was dropped, so the rows kept stay byte for byte. A file that cannot be read
    as this study's CSV (other header, not text) is refused in one line.
    """
    columns = result_columns(spec)

    def damaged(reason):
        return ParameterError(f"out: {path} is damaged ({reason}); choose another --out")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise damaged(f"cannot be read: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise damaged(f"not UTF-8 text at byte {exc.start}") from None
    if "\x00" in text:
        raise damaged("NUL bytes")
    lines = text.split("\n")
    if lines[0].split(",") != columns:
        raise ParameterError(f"out: {path} has other columns than this version writes; choose another --out")
    complete = lines[1:-1]                  # the last piece is "" or a line cut short
    plan = set(range(len(spec.cases())))
    controllers = set(spec.controllers)
    i_case, i_ctrl = columns.index("case"), columns.index("controller")
    kept, seen = [], set()
    for line in complete:
        try:
            row = next(csv.reader([line]))
            case = int(row[i_case])
        except (csv.Error, StopIteration, ValueError, IndexError):
            continue
        key = (case, row[i_ctrl] if len(row) > i_ctrl else None)
        if len(row) != len(columns) or case not in plan or key[1] not in controllers or key in seen:
            continue
        seen.add(key)
        kept.append((case, line))
    per_case = {}
    for case, _ in kept:
        per_case[case] = per_case.get(case, 0) + 1
    done = {c for c, n in per_case.items() if n == len(controllers)}
    rows = [line for case, line in kept if case in done]
    if len(rows) != len(complete) or lines[-1] != "":
        atomic_write_text(path, "\n".join([lines[0], *rows]) + "\n")
    return done


def read_results(path, spec: StudySpec | None = None):
    """``results.csv`` (a file or its folder) as a DataFrame, floats bit-exact.

    Parameters
    ----------
    path : str, Path or text stream
    spec : StudySpec, optional
        Orders the rows by case and the spec's controller order.

    Returns
    -------
    pandas.DataFrame
    """
    import pandas as pd
    if isinstance(path, (str, Path)) and Path(path).is_dir():
        path = Path(path) / _RESULTS
    exact = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}  # 3.x: default
    df = pd.read_csv(path, keep_default_na=False, na_values=[""], **exact)
    return _tidy(df, spec)


def _tidy(df, spec: StudySpec | None):
    for col in ("verdict", "error", "message"):
        if col in df:
            df[col] = df[col].astype(object).where(df[col].notna(), "" if col != "verdict" else None)
    if spec is not None and len(df):
        order = {n: i for i, n in enumerate(spec.controllers)}
        df = df.sort_values(["case", "controller"], key=lambda s: s.map(order) if s.name == "controller" else s)
    return df.reset_index(drop=True)


def _frame(rows: list, spec: StudySpec):
    """Rows as the DataFrame :func:`read_results` would give for them (same types and bits)."""
    return read_results(io.StringIO(_csv_text(rows, result_columns(spec), header=True)), spec)
