"""``cnctwin learn train|evaluate|inspect|lead-time``: models trained on recorded runs, as ONNX
files; an early-warning study of run outcomes."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from cnctwin import finite_json
from cnctwin.cli._options import MAX_SEED, JsonOutput

__all__ = ["app", "evaluate", "inspect", "lead_time", "train"]

app = typer.Typer(
    help="Learned models: train on recorded runs with grouped splits, evaluate, inspect.",
    no_args_is_help=True,
)

DataOpt = Annotated[
    list[str],
    typer.Option(
        "--data",
        help="Runs: a CSV/Parquet file, a folder or glob of them (one run per file: a "
        "historian export or a replay log), or historian:DB. Repeatable.",
    ),
]
LabelsOpt = Annotated[
    Path | None,
    typer.Option("--labels", help="Table (CSV/Parquet) of per-run labels, joined on --label-key."),
]
LabelKeyOpt = Annotated[
    str | None, typer.Option("--label-key", help="Column of --labels holding the run key.")
]


def _dataset(data: list[str], schema: Any, labels: Path | None, label_key: str | None) -> Any:
    from cnctwin.learn import build_dataset, read_runs, read_table

    table = read_table(labels) if labels is not None else None
    runs = read_runs(data, exclude=[labels] if labels is not None else [])
    return build_dataset(runs, schema, table, label_key)


def _print(report: dict[str, Any]) -> None:
    sys.stdout.write(finite_json.dumps(report) + "\n")


def train(
    data: DataOpt,
    features: Annotated[
        Path, typer.Option("--features", help="Feature spec (TOML, see examples/learn/).")
    ],
    target: Annotated[str, typer.Option("--target", help="Column to predict.")],
    group_by: Annotated[
        str, typer.Option("--group-by", help="Column of groups (run, experiment, case).")
    ],
    model: Annotated[str, typer.Option("--model", help="gpr, gbm, mlp or linear.")] = "gbm",
    out: Annotated[
        Path, typer.Option("--out", help="Model file; the report goes beside it.")
    ] = Path("model.onnx"),
    labels: LabelsOpt = None,
    label_key: LabelKeyOpt = None,
    holdout: Annotated[
        float, typer.Option("--holdout", help="Fraction of groups held out.", min=0.0, max=1.0)
    ] = 0.25,
    folds: Annotated[int, typer.Option("--folds", help="Grouped tuning folds.", min=2, max=50)] = 3,
    seed: Annotated[
        int, typer.Option("--seed", help="Seed of the hold-out draw.", min=0, max=MAX_SEED)
    ] = 0,
    quick: Annotated[bool, typer.Option("--quick", help="A smaller tuning grid.")] = False,
    max_gpr_points: Annotated[
        int, typer.Option("--max-gpr-points", help="Most GPR training rows.", min=10, max=20000)
    ] = 2000,
    leave_one_out: Annotated[
        bool,
        typer.Option(
            "--leave-one-out",
            help="Also hold out each group in turn (a model per group); MODEL.loo.json.",
        ),
    ] = False,
    as_json: JsonOutput = False,
) -> None:
    """Train a model on grouped data; write MODEL.onnx, MODEL.report.json and .png."""
    from cnctwin.learn import (
        FeatureSchema,
        export_onnx,
        leave_one_group_out,
        load_feature_spec,
        plot_report,
    )
    from cnctwin.learn import train as fit

    schema = FeatureSchema.from_spec(load_feature_spec(features))
    dataset = _dataset(data, schema, labels, label_key)
    result = fit(
        dataset,
        target,
        model,
        group_by,
        holdout=holdout,
        folds=folds,
        seed=seed,
        quick=quick,
        max_gpr_points=max_gpr_points,
    )
    export_onnx(result, schema, out)
    report_path = out.with_suffix(".report.json")
    figure = plot_report(result, out.with_suffix(".report.png"))
    report_path.write_text(finite_json.dumps(result.report, indent=1) + "\n")
    summary = {
        "model": str(out),
        "report": str(report_path),
        "figure": str(figure),
        "schema_sha256": schema.sha256,
        "groups_holdout": result.report["groups_holdout"],
        "holdout": result.report["holdout"],
    }
    if leave_one_out:
        loo = leave_one_group_out(
            dataset,
            target,
            model,
            group_by,
            folds=folds,
            seed=seed,
            quick=quick,
            max_gpr_points=max_gpr_points,
        )
        loo_path = out.with_suffix(".loo.json")
        loo_path.write_text(finite_json.dumps(loo, indent=1) + "\n")
        summary["leave_one_out"] = {"file": str(loo_path), "pooled": loo["pooled"]}
    if as_json:
        _print(summary)
        return
    metrics = result.report["holdout"]
    if result.task == "regression":
        line = (
            f"MAE {metrics['mae']:.4g}, RMSE {metrics['rmse']:.4g}, R2 {metrics['r2']:.3f}, "
            f"90% band coverage {metrics['band_coverage']:.2f}"
        )
    else:
        line = (
            f"balanced accuracy {metrics['balanced_accuracy']:.3f}, "
            f"ROC AUC {metrics['roc_auc']:.3f}"
        )
    held = result.report["groups_holdout"]
    shown = ", ".join(held) if len(held) <= 8 else f"{len(held)} groups"
    typer.echo(f"{model} -> {target}: held-out {group_by} {shown} ({metrics['rows']} rows): {line}")
    if leave_one_out:
        typer.echo(f"leave-one-{group_by}-out, pooled: {finite_json.dumps(loo['pooled'])}")
    typer.echo(f"wrote {out}, {report_path}, {figure}")


def evaluate(
    model_file: Annotated[Path, typer.Argument(help="A model written by `cnctwin learn train`.")],
    data: DataOpt,
    labels: LabelsOpt = None,
    label_key: LabelKeyOpt = None,
    features: Annotated[
        Path | None,
        typer.Option("--features", help="Check that this spec is the model's (refused if not)."),
    ] = None,
    group_by: Annotated[
        str | None, typer.Option("--group-by", help="Column of groups for per-group figures.")
    ] = None,
    as_json: JsonOutput = False,
) -> None:
    """Score a model on data, built with the schema stored in the model."""
    from cnctwin.learn import FeatureSchema, Predictor, evaluate_model, load_feature_spec

    predictor = Predictor.load(model_file)
    if features is not None:
        predictor.check_schema(
            FeatureSchema.from_spec(load_feature_spec(features)), f"--features {features}"
        )
    dataset = _dataset(data, predictor.schema, labels, label_key)
    report = evaluate_model(predictor, dataset, group_by)
    if as_json:
        _print(report)
        return
    typer.echo(finite_json.dumps(report, indent=1))


def inspect(
    model_file: Annotated[Path, typer.Argument(help="A model written by `cnctwin learn train`.")],
    as_json: JsonOutput = False,
) -> None:
    """Show a model's target, features (names, units, filters, windows) and hold-out score."""
    from cnctwin.learn import Predictor

    info = Predictor.load(model_file).describe()
    if as_json:
        _print(info)
        return
    model = info["model"]
    typer.echo(f"{info['file']}: {model['kind']} {model['task']} of {model['target']}")
    typer.echo(f"schema sha256 {info['schema_sha256']}, sample period {info['sample_period_s']} s")
    typer.echo(f"sources: {', '.join(info['sources'])}")
    for feature in info["features"]:
        typer.echo(f"  {feature['name']} [{feature['unit']}]")
    typer.echo(f"held out: {', '.join(map(str, info['groups_holdout'] or []))}")
    typer.echo(f"hold-out metrics: {finite_json.dumps(info['holdout'])}")


app.command("train")(train)
app.command("evaluate")(evaluate)
app.command("inspect")(inspect)


def lead_time(
    data: DataOpt,
    features: Annotated[
        Path, typer.Option("--features", help="Feature spec (TOML, a 'series' spec).")
    ],
    labels: Annotated[
        Path, typer.Option("--labels", help="Table (CSV/Parquet) of one row per run.")
    ],
    label_key: Annotated[str, typer.Option("--label-key", help="Column holding the run key.")],
    target: Annotated[str, typer.Option("--target", help="Column of each run's outcome.")],
    alarm: Annotated[str, typer.Option("--alarm", help="The outcome to flag early.")],
    phase_column: Annotated[
        str, typer.Option("--phase-column", help="Column of the runs holding the phase.")
    ],
    active_prefix: Annotated[
        str,
        typer.Option("--active-prefix", help="Samples whose phase starts with this are scored."),
    ],
    smooth: Annotated[
        int,
        typer.Option("--smooth", help="Samples the online rule averages.", min=1, max=100_000),
    ] = 20,
    out: Annotated[
        Path, typer.Option("--out", help="Report (JSON); the figure goes beside it (.png).")
    ] = Path("lead_time.json"),
    as_json: JsonOutput = False,
) -> None:
    """Flag a run's outcome online, each run left out in turn; lead times, false alarms."""
    from cnctwin.learn import (
        AlarmRule,
        FeatureSchema,
        lead_time_study,
        load_feature_spec,
        outcomes,
        plot_lead_time,
        read_runs,
        read_table,
    )

    schema = FeatureSchema.from_spec(load_feature_spec(features))
    outcome = outcomes(read_table(labels), label_key, target)
    runs = read_runs(data, exclude=[labels])
    result = lead_time_study(
        runs, schema, outcome, AlarmRule(alarm, phase_column, active_prefix, smooth)
    )
    out.write_text(finite_json.dumps(result.report, indent=1) + "\n")
    figure = plot_lead_time(result, out.with_suffix(".png"))
    summary = result.report["summary"]
    if as_json:
        _print({"report": str(out), "figure": str(figure), **summary})
        return
    for run in result.report["runs"]:
        if run["flagged"]:
            when = (
                f"flagged at {run['flag_time_s']:.1f} s, {run['before_end_s']:.1f} s before "
                f"the end of machining"
            )
        else:
            when = "not flagged"
        kind = {
            (True, True): "caught",
            (True, False): "missed",
            (False, True): "false alarm",
            (False, False): "quiet",
        }[(run["alarm"], run["flagged"])]
        typer.echo(f"run {run['run']:>4} ({target} = {run['outcome']}, {kind}): {when}")
    typer.echo(
        f"{target} = {alarm}: {summary['alarm_runs_flagged']} of {summary['alarm_runs']} "
        f"runs flagged; false alarms on {summary['false_alarms']} of "
        f"{summary['other_runs']} other runs; window ROC AUC "
        f"{summary['window_roc_auc_leave_one_run_out']:.3f} left out by run "
        f"({summary['window_roc_auc_random_windows']:.3f} by random windows, leakage)"
    )
    typer.echo(f"wrote {out}, {figure}")


app.command("lead-time")(lead_time)
