"""``python -m simbench``: simulate, run estimators, write results and a report; and the subcommands.

The Hydra app composes ``conf/config.yaml``. Each Hydra job is one scenario
(config + seed) with the selected estimators (:func:`simbench.runs.jobs.run_job`);
after a run or a multirun the :class:`simbench.cli.callbacks.FinalizeRun` callback
aggregates the job files into ``summary.parquet``/``epochs.parquet`` and
builds ``claims.csv`` and ``report/``.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Glob
from hydra.errors import HydraException
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict

from simbench.cli.command_line import check_no_sweep, check_subcommand, run_hydra, unresolved
from simbench.cli.text import one_line_warnings
from simbench.entry_points import ALL_ESTIMATORS
from simbench.errors import SimbenchError, did_you_mean
from simbench.runs.groups import (
    CONF_DIR,
    available,
    check_group_choices,
    config_groups,
    recorded_built_in_estimators,
)
from simbench.runs.run_dirs import unique_run_dir

if TYPE_CHECKING:
    import pandas

    from simbench.runs.compose import Schemas

# ``--help`` and a misspelt name answer from the names above in well under a second; what runs a job,
# composes a config or draws a table (estimators, pandas, Hydra's config store: seconds) is imported
# where it is needed (``# lazy:``).

#: ``python -m simbench NAME ...``: the commands beside Hydra runs and sweeps, each a module of
#: ``simbench.cli`` whose ``main(argv)`` returns the exit code (imported when it runs).
SUBCOMMANDS: dict[str, str] = {
    "report": "report",
    "export": "export",
    "score": "score",
    "tables": "tables",
    "validate": "validate",
    "zero-baseline": "zero_baseline",
}


@hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
def _app(cfg: DictConfig) -> None:
    one_line_warnings()  # again: a launcher may run the job in another process
    hc = HydraConfig.get()
    with open_dict(cfg):
        if hc.mode == RunMode.MULTIRUN:
            # the sweep directory is resolved once by the launcher; a ${now:} in results_dir is not
            cfg.results_dir = hc.sweep.dir
        if cfg.blas_threads is None:  # a cluster job uses the CPUs its launcher reserved (submitit)
            cfg.blas_threads = hc.launcher.get("cpus_per_task")
    from simbench.cli.progress import job_progress  # lazy: a job's imports, not --help's
    from simbench.cli.terminal import compact_summary  # lazy: pandas
    from simbench.runs.jobs import run_job  # lazy: every estimator

    multirun = hc.mode == RunMode.MULTIRUN
    job = f"job{hc.job.num}" if multirun else None  # a sweep's job reports to the parent's bar through a file
    try:
        with job_progress(cfg.progress, len(cfg.estimator), cfg.results_dir, job) as bar:
            rows = run_job(cfg, fail_fast=not multirun, bar=bar)
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    if not multirun:
        print(compact_summary(rows))


def main() -> None:
    """Entry point: a subcommand (:data:`SUBCOMMANDS`), or a Hydra run or sweep.

    A run is composed and checked (:func:`simbench.runs.checks.check_run`) up front, a
    command-line sweep once per swept value (:func:`job_overrides`), so a bad override
    gets one line, not Hydra's error page or a ``failed`` row hours later.

    Exit codes: 0 when every row is ``ok``, ``skipped`` or ``diverged``; 1 when a row
    ``failed`` (:class:`simbench.cli.callbacks.FinalizeRun`, after every job has run);
    2 when a config is refused (a :class:`SimbenchError`), before any job.
    """
    one_line_warnings()
    args = sys.argv[1:]
    if args and args[0] in SUBCOMMANDS:
        command = importlib.import_module(f"simbench.cli.{SUBCOMMANDS[args[0]]}")  # dynamic: a module of SUBCOMMANDS
        sys.exit(command.main(args[1:]))
    if any(a in ("-h", "--help") for a in args):
        print(help_text())
        return
    reserved: Path | None = None
    try:
        check_subcommand(args, SUBCOMMANDS)
        # group options are checked for sweeps and flags too: Hydra would only say "Could not load"
        suggest_names(a for a in args if not a.startswith("-"))
        if "--estimators" in args:
            from tabulate import tabulate  # lazy: --help and a misspelt name need none of these

            from simbench.runs.compose import register_schemas  # lazy

            register_schemas()  # a broken plug-in estimator stops here, in one line naming its package
            print(tabulate(estimator_table(), headers="keys", tablefmt="plain", showindex=False))
            return
        first = check_command_line(args)
        if first is not None and "${now:" in str(unresolved(first, "results_dir")):
            # the default folder is named by the second it starts in: two runs of one second get one each
            reserved = unique_run_dir(Path(first.results_dir))
            sys.argv.append(f"results_dir={reserved}")
    except SimbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    try:
        run_hydra(_app)
    finally:
        if reserved is not None and reserved.is_dir() and not any(reserved.iterdir()):
            reserved.rmdir()  # nothing ran (Hydra refused the command line): no empty folder left behind


def check_command_line(args: list[str]) -> DictConfig | None:
    """Compose and check the command line of a run or sweep before Hydra runs it; return the first job's config.

    First with the schemas recorded at the last registration (:func:`simbench.runs.schema_record.read_record`),
    which import no estimator and no simulation, so a refused value takes about a second; when the record is
    stale or cannot tell (a source whose check it lacks), with the real classes. Then the real classes are
    registered for Hydra's own composition of the run. A sweep of studies (``+sweep=thesis``) runs here.

    Raises
    ------
    SimbenchError
        For the first problem, in one line (:func:`simbench.runs.checks.check_run`, a broken plug-in).
    """
    from simbench.runs.compose import recorded_schemas, register_schemas  # lazy: every estimator's Config
    from simbench.runs.schema_record import NotRecorded, read_record  # lazy

    record = read_record()
    first: DictConfig | None = None
    try:
        if record is None:
            raise NotRecorded("no current record")
        first = check_configs(args, recorded_schemas(record))
    except NotRecorded:
        register_schemas()  # a broken plug-in estimator stops here, in one line naming its package
        first = check_configs(args, None)
    register_schemas()  # the classes the run composes with (Hydra, in _app)
    return first


def check_configs(args: list[str], schemas: Schemas | None) -> DictConfig | None:
    """:func:`check_command_line` with one set of schemas (None: the real classes): compose the config,
    run a sweep of studies, check every job (:func:`check_jobs`) and count a sweep's jobs for the bar.

    Raises
    ------
    SimbenchError
        For the first problem, in one line.
    NotRecorded
        With recorded schemas, when the record cannot tell, or for a sweep of studies.
    """
    from simbench.cli.progress import Planned  # lazy
    from simbench.runs.compose import compose_config  # lazy
    from simbench.runs.schema_record import NotRecorded  # lazy

    shaping = config_overrides(args)
    cfg = compose_config(shaping, with_hydra=True, schemas=schemas) if shaping is not None else None
    if cfg is not None and "studies" in cfg:  # a sweep of sweeps (thesis): studies x worlds
        if schemas is not None:
            raise NotRecorded("a sweep of studies")  # its studies compose with the real classes
        from simbench.cli.studies import run_studies  # lazy: the report's imports (matplotlib)
        from simbench.runs.checks import check_report_formats  # lazy
        from simbench.runs.studies import StudiesConfig  # lazy

        formats = OmegaConf.select(cfg, "report.formats", default=None)
        check_report_formats(formats)  # before the first study, not after the last
        formats = list(formats or ["png"])
        sys.exit(run_studies(StudiesConfig.from_config(cfg), Path(cfg.results_dir), args, formats))
    multirun = any(a in RUN_FLAGS for a in args) or (
        cfg is not None and OmegaConf.select(cfg, "hydra.mode") == RunMode.MULTIRUN
    )
    if cfg is not None and not multirun:
        check_no_sweep(args)
    first = check_jobs(args, (shaping, cfg) if shaping is not None and cfg is not None else None, schemas)
    cfg = cfg if cfg is not None else first  # -m: composed for the checks only
    if cfg is not None and multirun:
        Planned.jobs = planned_jobs(args, cfg)
    return first


def help_text() -> str:
    """``--help``: the template of ``conf/config.yaml``'s ``hydra.help``, resolved here.

    Hydra's own ``--help`` formats every config group's options twice whether the template
    shows them or not (8 s); this template lists the groups itself (``${simbench_config_groups:}``).
    """
    node = OmegaConf.load(CONF_DIR / "config.yaml").hydra.help
    return str(OmegaConf.create({"hydra": {"help": node}}).hydra.help.template)


def suggest_names(overrides: Iterable[str]) -> None:
    """Refuse a misspelt option or estimator name with the closest known one (``did you mean 'dcs'?``).

    Covers group options (``estimator=[l2,dsc]``, ``scenario=urbn``) and the estimator of an
    ``estimator.<name>.<field>`` key; other keys are left to the config checks.

    Raises
    ------
    SimbenchError
        Naming the unknown name, the suggestion and the known names.
    """
    for item in overrides:
        check_group_choices([item], every_estimator=all_estimator_options)
        key, sep, _ = item.partition("=")
        parts = key.lstrip("+~").split(".")
        if sep and len(parts) > 2 and parts[0] == "estimator":
            known = [name for name in available("estimator") if name != ALL_ESTIMATORS]
            if parts[1] not in known:
                known = [name for name in all_estimator_options() if name != ALL_ESTIMATORS]
            if parts[1] not in known:
                raise SimbenchError(
                    f"estimator.{parts[1]}",
                    f"unknown estimator '{parts[1]}'{did_you_mean(parts[1], known)}",
                    f"choose from {', '.join(known)} (python -m simbench --estimators lists them)",
                )


def all_estimator_options() -> list[str]:
    """The ``estimator`` options, certainly: when the built-in names recorded at the last registration are
    stale (an estimator file changed since), every estimator is imported and registered (seconds) to tell."""
    if recorded_built_in_estimators() is not None:
        return available("estimator")
    import estimators  # lazy: only to refuse a name the recorded ones lack
    from simbench.runs.compose import record_estimator_names  # lazy

    record_estimator_names()  # for the next command line
    return available("estimator", estimators.registered())


def planned_jobs(args: list[str], cfg: DictConfig) -> int | None:
    """How many jobs a command-line sweep runs: the product of its sweeps' lengths (with a sweep
    file's params where the command line does not set the key); None when Hydra alone can tell
    (``glob(...)``, or a parameter it cannot parse here)."""
    given = [a for a in args if a not in RUN_FLAGS]
    params = OmegaConf.select(cfg, "hydra.sweeper.params", default=None) or {}
    keys = {a.partition("=")[0].lstrip("+~") for a in given}
    given += [f"{k}={v}" for k, v in params.items() if k not in keys]
    try:
        parsed = OverridesParser.create().parse_overrides(given)
        total = 1
        for override in parsed:
            if override.is_sweep_override() and not override.key_or_group.startswith("hydra."):
                total *= len(list(override.sweep_string_iterator()))
    except HydraException:
        return None
    return total


def config_overrides(args: list[str]) -> list[str] | None:
    """The command-line arguments that shape the config: all but sweeps and ``hydra.*`` settings.

    Hydra expands sweeps per job and applies its own settings itself; a setting like
    ``hydra.sweeper.params.seed=0`` does not even compose for a sweep file without
    sweeper params (``thesis``, whose studies it is meant for).

    None when there is a flag (``-m``, ``--help``) or an argument Hydra's parser
    rejects: Hydra then handles the command line itself.
    """
    if any(a.startswith("-") for a in args):
        return None
    try:
        parsed = OverridesParser.create().parse_overrides(args)
    except HydraException:
        return None
    return [a for a, o in zip(args, parsed) if not o.is_sweep_override() and not o.key_or_group.startswith("hydra.")]


def check_jobs(
    args: list[str], composed: tuple[list[str], DictConfig] | None = None, schemas: Schemas | None = None
) -> DictConfig | None:
    """Compose and check (:func:`simbench.runs.checks.check_run`) every job config of a run or sweep.

    The override lists are :func:`job_overrides`'s, with the sweeper params of a sweep file
    (``+sweep=ch5_sensitivity``: ``prior_scale: 0.1,...,100``) added where the command line
    does not set the key, as Hydra's sweeper adds them.

    Parameters
    ----------
    args : list of str
        The command line.
    composed : (list of str, DictConfig), optional
        Overrides and the config the caller composed from them ``with_hydra``: reused when they
        are the first job's.
    schemas : Schemas, optional
        The schemas to compose and check with (:func:`simbench.runs.compose.recorded_schemas`); None: the real ones.

    Returns
    -------
    DictConfig or None
        The first job's config (``with_hydra``); None when Hydra handles the command line itself.

    Raises
    ------
    SimbenchError
        For the first config refused, in one line.
    """
    from simbench.runs.checks import check_run  # lazy: --help needs neither
    from simbench.runs.compose import compose_config  # lazy

    jobs = job_overrides(args)
    if not jobs:
        return None
    if composed is not None and composed[0] == jobs[0]:
        first = composed[1]
    else:
        first = compose_config(jobs[0], with_hydra=True, schemas=schemas)
    given = {item.partition("=")[0].lstrip("+~") for item in jobs[0]}
    params = OmegaConf.select(first, "hydra.sweeper.params", default=None) or {}
    from_file = [f"{key}={value}" for key, value in params.items() if key not in given]
    if from_file:
        jobs = job_overrides([*args, *from_file]) or jobs
    else:
        check_run(first, schemas)
        jobs = jobs[1:]
    for overrides in jobs:
        check_run(compose_config(overrides, schemas=schemas), schemas)
    return first


#: The flags of a run or sweep whose configs :func:`job_overrides` can check; with any other
#: (``--help``, ``--cfg job``, ...) Hydra handles the command line itself.
RUN_FLAGS = ("-m", "--multirun")


def job_overrides(args: list[str]) -> list[list[str]] | None:
    """The override lists to compose and check before a run or a command-line sweep starts.

    The first holds every argument but ``hydra.*`` settings, each sweep at its first value
    (without sweeps it is :func:`config_overrides`'s list); then one list per further value
    of each sweep (``a,b``, ``choice(...)``, ``range(...)``), the other sweeps at their
    first, so a bad value anywhere in ``-m estimator.dcs.prior_scale=1,-1`` stops the sweep
    before its first job. A seed sweep gives its first value only (no check depends on the
    seed); ``glob(...)`` sweeps are left to Hydra, and a sweep file's params to :func:`check_jobs`.

    None when there is another flag (``--help``) or an argument Hydra's parser rejects:
    Hydra then handles the command line itself.

    Raises
    ------
    SimbenchError
        For a sweep of no value (``seed=range(5,0)``, a ``glob(...)`` matching no option of its
        group), which Hydra would run as 0 jobs and exit 0.
    """
    if any(a.startswith("-") and a not in RUN_FLAGS for a in args):
        return None
    given = [a for a in args if a not in RUN_FLAGS]
    try:
        parsed = OverridesParser.create().parse_overrides(given)
    except HydraException:
        return None
    fixed: list[str] = []
    swept: list[tuple[str, list[str]]] = []
    for arg, override in zip(given, parsed):
        if override.key_or_group.startswith("hydra."):
            continue
        if not override.is_sweep_override():
            fixed.append(arg)
            continue
        key = override.get_key_element()
        value = override.value()
        if isinstance(value, Glob):  # its options are a group's files (Hydra's config loader expands it)
            group = key.lstrip("+~")
            if group in config_groups() and not value.filter(available(group)):
                raise SimbenchError(
                    key, f"'{arg}' matches no {group} option: 0 jobs", f"choose from {', '.join(available(group))}"
                )
            continue
        values = list(override.sweep_string_iterator())
        if not values:
            raise SimbenchError(
                key, f"'{arg}' sweeps no value: 0 jobs", "give a sweep of at least one value, e.g. seed=range(0,5)"
            )
        if override.key_or_group == "seed":  # one composition will do
            values = values[:1]
        swept.append((key, values))
    first = [f"{key}={values[0]}" for key, values in swept]
    jobs = [[*fixed, *first]]
    for i, (key, values) in enumerate(swept):
        jobs += [[*fixed, *first[:i], f"{key}={value}", *first[i + 1 :]] for value in values[1:]]
    return jobs


def family_package(module: str) -> str:
    """The family package of a built-in estimator's module (``estimators.batch.bce`` -> ``batch``); a
    plug-in's module as it is."""
    parts = module.split(".")
    return parts[1] if parts[0] == "estimators" and len(parts) > 2 else module


def estimator_table() -> pandas.DataFrame:
    """The registered estimators (``python -m simbench --estimators``).

    Returns
    -------
    pandas.DataFrame
        Columns ``name``, ``family`` (the module defining the class, without the
        ``estimators.`` prefix of the built-ins), ``source`` (``built-in`` or the
        plug-in's package) and ``description`` (the first line of the class docstring).
    """
    import pandas as pd  # lazy: --help does not list the estimators

    import estimators  # lazy

    rows = [
        {
            "name": name,
            "family": family_package(cls.__module__),
            "source": estimators.source(name),
            "description": (inspect.getdoc(cls) or "").partition("\n")[0],
        }
        for name, cls in estimators.registered().items()
    ]
    return pd.DataFrame(rows, columns=["name", "family", "source", "description"])
