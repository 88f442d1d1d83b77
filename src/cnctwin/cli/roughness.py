"""``cnctwin roughness``: fit the power-law roughness model to measured cuts, and predict with it.

``fit`` reads a CSV with a header row and one row per cut, fits
``Ra = b0 ap^b1 S^b2 fz^b3 V^b4`` (Royandi 2026, Eq. 23) and prints the model; its ``--json``
output is the model file that ``predict --model`` reads. Guide: docs/roughness.md.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.errors import DataError
from cnctwin.measurements import read_columns
from cnctwin.quality import PowerLawFit, fit_power_law, read_power_law_model

__all__ = ["app", "fit", "fit_report", "predict"]

app = typer.Typer(
    help="Surface roughness: fit the power-law model to cuts, predict with it.",
    no_args_is_help=True,
)

#: The columns ``fit`` uses unless told otherwise (Royandi 2026's model and units).
DEFAULT_TARGET = "ra_um"
DEFAULT_FEATURES = ("ap_mm", "spindle_rpm", "fz_mm", "vibration_g")
#: Largest value of a feature (any unit): the power law takes positive values; beyond 1e9 in
#: mm, rpm or g a value is a typing error.
MAX_FEATURE = 1e9
_OPTIONS = dict(zip(DEFAULT_FEATURES, ("--ap-mm", "--rpm", "--fz-mm", "--vib-g"), strict=True))


@app.callback()
def _roughness() -> None:
    """Surface roughness: fit the power-law model to cuts, predict with it."""


def fit_report(fitted: PowerLawFit, source: str) -> dict[str, Any]:
    """The JSON of ``cnctwin roughness fit``, which is also the model file of ``predict``.

    Parameters
    ----------
    fitted
        The fitted model with its in-sample metrics.
    source
        Where the samples came from.

    Returns
    -------
    dict
        ``target``, ``b0``, ``ln_b0``, ``exponents`` (by feature name, in fitting order),
        ``r2``, ``r2_correlation``, ``mape_percent``, ``rmse`` (in the target's unit),
        ``samples`` and ``source``.
    """
    model, metrics = fitted.model, fitted.metrics
    return {
        "target": model.target,
        "b0": model.b0,
        "ln_b0": model.ln_b0,
        "exponents": dict(model.exponents),
        "r2": metrics.r2,
        "r2_correlation": metrics.r2_correlation,
        "mape_percent": metrics.mape_percent,
        "rmse": metrics.rmse,
        "samples": metrics.samples,
        "source": source,
    }


@app.command()
def fit(
    data: Annotated[Path, typer.Argument(help="CSV: a header row, then one row per cut.")],
    target: Annotated[
        str, typer.Option("--target", help="Column of the measured roughness.")
    ] = DEFAULT_TARGET,
    features: Annotated[
        str, typer.Option("--features", help="Comma-separated columns of the features.")
    ] = ",".join(DEFAULT_FEATURES),
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object (the model file of predict).")
    ] = False,
) -> None:
    """Fit Ra = b0 ap^b1 S^b2 fz^b3 V^b4 (Royandi 2026, Eq. 23) by log-linear least squares."""
    names = [name.strip() for name in features.split(",") if name.strip()]
    if not names:
        raise DataError(f"--features {features!r}; give column names separated by commas")
    if target in names:
        raise DataError(f"--target {target!r} is also a feature; a column cannot be both")
    columns = read_columns(data, [*names, target])
    fitted = fit_power_law(
        {name: columns[name] for name in names}, columns[target], target_name=target
    )
    report = fit_report(fitted, str(data))
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=f"roughness fit: {data}", show_header=False, title_justify="left")
    terms = (f"{name}^b{i}" for i, name in enumerate(fitted.model.features, start=1))
    table.add_row("model", f"{target} = b0 * " + " * ".join(terms))
    table.add_row("b0", f"{report['b0']:.6g} (ln b0 = {report['ln_b0']:.6f})")
    for name, exponent in report["exponents"].items():
        table.add_row(f"exponent of {name}", f"{exponent:.6f}")
    table.add_row("samples", str(report["samples"]))
    table.add_row("R^2 (1 - SSres/SStot)", f"{report['r2']:.4f}")
    table.add_row("R^2 (correlation^2)", f"{report['r2_correlation']:.4f}")
    table.add_row("MAPE", f"{report['mape_percent']:.2f} %")
    table.add_row("RMSE", f"{report['rmse']:.4g} ({target})")
    Console().print(table)


@app.command()
def predict(
    model_file: Annotated[
        Path, typer.Option("--model", help="Model file: the JSON of 'roughness fit --json'.")
    ],
    ap_mm: Annotated[
        float | None, typer.Option("--ap-mm", help="Axial depth of cut, mm (feature ap_mm).")
    ] = None,
    rpm: Annotated[
        float | None, typer.Option("--rpm", help="Spindle speed, rpm (feature spindle_rpm).")
    ] = None,
    fz_mm: Annotated[
        float | None, typer.Option("--fz-mm", help="Feed per tooth, mm (feature fz_mm).")
    ] = None,
    vib_g: Annotated[
        float | None,
        typer.Option("--vib-g", help="RMS vibration, g, measured or simulated (vibration_g)."),
    ] = None,
    values: Annotated[
        list[str] | None,
        typer.Option("--value", help="NAME=NUMBER for a feature of another name (repeatable)."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Predict roughness at one cutting condition with a fitted model."""
    given: dict[str, float] = {
        name: value
        for name, value in zip(DEFAULT_FEATURES, (ap_mm, rpm, fz_mm, vib_g), strict=True)
        if value is not None
    }
    for name, value in given.items():
        if not 0.0 < value <= MAX_FEATURE:  # False for NaN too
            raise DataError(
                f"{_OPTIONS[name]}: {name!r} is {value!r}; give 0 < value <= {MAX_FEATURE:g}"
            )
    model = read_power_law_model(model_file, DEFAULT_TARGET)
    for item in values or []:
        name, sep, text = item.partition("=")
        try:
            number = float(text)
        except ValueError:
            number = math.nan
        if not (sep and name.strip() and 0.0 < number <= MAX_FEATURE):
            raise DataError(
                f"--value {item!r}; give NAME=NUMBER with 0 < NUMBER <= {MAX_FEATURE:g}, "
                "e.g. --value vibration_g=2.5"
            )
        given[name.strip()] = number
    missing = [name for name in model.features if name not in given]
    if missing:
        hints = [_OPTIONS.get(name, f"--value {name}=...") for name in missing]
        raise DataError(
            f"the model needs {', '.join(missing)}; give {', '.join(hints)} ({model_file})"
        )
    inputs = {name: given[name] for name in model.features}
    value = float(model.predict(inputs))
    if as_json:
        sys.stdout.write(finite_json.dumps({model.target: value, "inputs": inputs}) + "\n")
        return
    typer.echo(f"{model.target} = {value:.4g}")
