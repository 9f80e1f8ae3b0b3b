"""The door of a run: every check of a composed config that needs no data, before any job starts.

:func:`check_run` is what ``python -m simbench`` and :func:`simbench.run` call on each
composed config (for a sweep, on one config per swept value), so a bad value stops the
run in one line and about a second, not as a ``failed`` row hours into a sweep. It
checks the output folder, the estimator selection, the data config (the source's own
check, e.g. :func:`~simbench.sim.config.validate_sim`, with its cross-field and memory
checks), every selected estimator's ``Config`` (``validate``) and the report's options
(``report.formats``, :func:`check_report_formats`), which are read only after the last job. The job itself
runs the same source and estimator checks again (a job may run in another process);
they are cheap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

from omegaconf import DictConfig, OmegaConf

import estimators
from estimators.base import validate_config
from simbench.bounds import FINITE_ONLY, check_bounds
from simbench.errors import SimbenchError
from simbench.runs.compose import Schemas, estimator_node
from simbench.runs.files import check_output_dir
from simbench.runs.scenarios import check_scenario, scenario_settings
from simbench.runs.schema_record import NotRecorded, Record, known_valid, real_class, remember_valid, source_check
from simbench.source_registry import SIMULATED, SourceConfig
from simbench.typed import to_typed

#: A file format of the report's figures: the page shows the PNG; PDF and SVG are for a paper.
ReportFormat = Literal["png", "pdf", "svg"]
#: Every :data:`ReportFormat`, the values ``report.formats`` may list.
REPORT_FORMATS: tuple[ReportFormat, ...] = ("png", "pdf", "svg")
#: The figure size presets ``report.style`` may name (simbench.report.style.PRESETS): the page, a paper's
#: single (3.5 in) or double (7 in) column.
REPORT_STYLES = ("screen", "single", "double")


def check_run(cfg: DictConfig, schemas: Schemas | None = None) -> None:
    """Raise a one-line :class:`SimbenchError` for the first problem of a composed run config.

    Parameters
    ----------
    cfg : DictConfig
        A composed ``conf/config.yaml`` (:func:`simbench.runs.compose.compose_config`).
    schemas : Schemas, optional
        The recorded schemas ``cfg`` was composed with (:func:`simbench.runs.compose.recorded_schemas`):
        the same checks, in the same order, importing only what they need (:func:`check_recorded`).
        None: the real classes.

    Raises
    ------
    SimbenchError
        Naming the field: ``results_dir`` (:func:`check_results_dir`), ``estimator`` (none
        selected), a scenario, receiver or IMU field (the source's check), a key a ``+``
        override added that the typed schema lacks, ``estimator.<name>.<field>``,
        ``report.formats`` (:func:`check_report_formats`), ``seed`` (:func:`check_seed`) or ``progress``.
    """
    check_results_dir(str(cfg.results_dir))
    check_report_formats(OmegaConf.select(cfg, "report.formats", default=None))
    check_report_style(OmegaConf.select(cfg, "report.style", default=None))
    check_seed(OmegaConf.select(cfg, "seed", default=0))
    progress = OmegaConf.select(cfg, "progress", default=True)
    if not isinstance(progress, bool):
        raise SimbenchError("progress", f"'{progress}' is not true or false", "use progress=true or progress=false")
    selected = list(cfg.get("estimator") or {})  # estimator=[] composes to no node at all
    if not selected:
        raise SimbenchError(
            "estimator", "no estimator selected", "pick one or more, e.g. estimator=[l2], or estimator=all"
        )
    if schemas is not None and schemas.record is not None:
        check_recorded(cfg, selected, schemas.sources, schemas.estimators, schemas.record)
        return
    check_scenario(scenario_settings(cfg))
    passed: list[tuple[str, dict[str, Any]]] = []
    try:
        for name in selected:
            where, node = f"estimator.{name}", estimator_node(cfg, name)
            validate_config(to_typed(node, estimators.get(name).Config, where), where)
            passed.append((name, node))
    finally:  # for the next command line's door (check_recorded)
        remember_valid(passed)


def check_recorded(
    cfg: DictConfig,
    selected: Sequence[str],
    source_configs: Mapping[str, type],
    estimator_configs: Mapping[str, type],
    record: Record,
) -> None:
    """:func:`check_run`'s data and estimator checks with recorded schemas, in its order and words.

    The scenario: typed by its source's real ``Config`` and checked by the recorded check
    (:func:`simbench.runs.schema_record.source_check`). Each estimator: a node that passed its checks
    under this code before is not checked again (:func:`known_valid`); any other is typed by the
    rebuilt ``Config`` and checked for non-finite numbers (what :func:`validate_config` checks first,
    without code), then checked by its real class, imported then.

    Raises
    ------
    SimbenchError
        As :func:`check_run`.
    NotRecorded
        When the source's ``Config`` or check is not recorded as light (then :func:`check_run` asks the real classes).
    """
    source = str(cfg.scenario.get("source", SIMULATED))
    config, check = source_configs.get(source), source_check(record, source)
    if config is None or check is None or not issubclass(config, SourceConfig):
        raise NotRecorded(f"source '{source}'")
    check(scenario_settings(cfg, config))
    passed: list[tuple[str, dict[str, Any]]] = []
    try:
        for name in selected:
            where, node = f"estimator.{name}", estimator_node(cfg, name)
            if known_valid(record, name, node):
                continue
            check_bounds(to_typed(node, estimator_configs[name], where), where, FINITE_ONLY)
            real = real_class(record.estimators[name]["config"])
            validate_config(to_typed(node, real, where), where)
            passed.append((name, node))
    finally:  # those before a refused one passed too
        remember_valid(passed)


#: Seeds are stored as int64 in the result tables (and numpy's generators take any non-negative integer).
MAX_SEED = 2**63 - 1


def check_seed(seed: Any, field: str = "seed", example: str = "seed=0 or -m seed=range(5)") -> None:
    """Raise a one-line :class:`SimbenchError` naming ``field`` unless ``seed`` is an integer in ``0 .. MAX_SEED``.

    Checked at the door: a negative seed failed in numpy's generator and a huge one overflowed the
    result table, both after the progress bar started (the second after the estimators ran).
    ``field`` and ``example`` are a subcommand's own (``--seed``, ``--seed 0``).
    """
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise SimbenchError(
            field, f"{seed!r} is not an integer in 0 .. 2**63-1", f"give a non-negative seed, e.g. {example}"
        )


def check_report_formats(formats: Sequence[str] | str | None) -> None:
    """Raise a one-line :class:`SimbenchError` unless ``formats`` lists only :data:`REPORT_FORMATS`.

    Checked at the door because the report is built after the last job: a misspelt format
    would otherwise end an hour-long sweep with no report.

    Parameters
    ----------
    formats : sequence of str, str or None
        ``report.formats``; None (the key is absent) means PNG only.

    Raises
    ------
    SimbenchError
        Naming ``report.formats``, the unknown values and the allowed ones; also for a bare
        word (``report.formats=pdf``), which is not a list.
    """
    if formats is None:
        return
    allowed = ", ".join(REPORT_FORMATS)
    if isinstance(formats, str):
        raise SimbenchError(
            "report.formats", f"is '{formats}', not a list", f"write a list, e.g. report.formats=[png,{formats}]"
        )
    unknown = [str(f) for f in formats if f not in REPORT_FORMATS]
    if unknown:
        raise SimbenchError("report.formats", f"unknown {', '.join(unknown)}", f"choose from {allowed}")


def check_report_style(style: str | None) -> None:
    """Raise a one-line :class:`SimbenchError` unless ``style`` (``report.style``; None: absent) is one of
    :data:`REPORT_STYLES`."""
    if style is not None and style not in REPORT_STYLES:
        raise SimbenchError(
            "report.style", f"is '{style}', not one of {', '.join(REPORT_STYLES)}", "e.g. report.style=double"
        )


def check_results_dir(path: str) -> None:
    """Raise a one-line :class:`SimbenchError` unless ``path`` names a folder simbench can write
    (:func:`simbench.runs.files.check_output_dir`, as every subcommand checks its output folder).

    An existing folder must be writable; a missing one is created by the run, so the
    nearest existing parent must be a writable folder. It is not created here: the
    default ``results/run-${now:...}`` resolves to another second when the run starts.

    Raises
    ------
    SimbenchError
        For an empty path (the run would land in the working directory), a regular file,
        or a folder the process cannot write in.
    """
    if not path.strip():
        raise SimbenchError(
            "results_dir",
            "is empty, so the run would write into the working directory",
            "give a folder, e.g. results_dir=results/run",
        )
    check_output_dir("results_dir", path, "results_dir=results/run")
