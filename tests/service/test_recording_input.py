"""What a recording upload reads from its input: numbers that fit the float32 samples are stored in, CSVs as
plate software writes them (tab or semicolon, ``COPx[cm]``, ``Time[s]``), and the length unit a file
declares, which the request's ``units`` must not contradict."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.service.helpers import created, make_demonstrator
from tests.service.test_force_plate_files import COP, c3d_bytes
from tests.shared_data import shared_data


def url(dem: dict[str, Any]) -> str:
    """The demonstrator's recordings."""
    return f"/v1/demonstrators/{dem['id']}/recordings"


def upload(client: TestClient, auth: dict[str, str], filename: str, data: bytes, **fields: Any) -> Any:
    """POST a file as a standing trial of a new demonstrator, with form fields (objects as JSON)."""
    form = {"protocol": "standing"} | {
        k: v if isinstance(v, str) else json.dumps(v) for k, v in fields.items()
    }
    dem = make_demonstrator(client, auth)
    return client.post(url(dem), files={"file": (filename, data)}, data=form, headers=auth)


def errors(response: Any) -> list[dict[str, str]]:
    """The errors of a 422 problem+json answer."""
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    return list(response.json()["errors"])


def walk(n: int = 400) -> np.ndarray:
    """(n, 3) columns t, x, y at 100 Hz: a COP wandering about a point, in cm."""
    rng = np.random.default_rng(3)
    return np.column_stack([np.arange(n) / 100, np.cumsum(rng.normal(0, 0.01, (n, 2)), axis=0)])


def table(header: list[str], rows: np.ndarray, delimiter: str = ",") -> bytes:
    """A CSV of `rows` under `header`, cells joined by `delimiter`."""
    lines = [delimiter.join(header)] + [delimiter.join(f"{v:.6f}" for v in row) for row in rows]
    return ("\n".join(lines) + "\n").encode()


# ------------------------------------------------------------------ values past float32's range


def test_a_json_sample_past_float32s_range_is_a_422_naming_it(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    samples = [{"t": t, "x": x, "y": y} for t, x, y in walk().tolist()]
    samples[5]["x"] = samples[5]["y"] = 1e39  # two columns of one sample, in column order
    samples[-1]["t"] = 1e39
    found = errors(client.post(url(dem), json={"protocol": "standing", "samples": samples}, headers=auth))
    assert [e["pointer"] for e in found] == ["/samples/5/x", "/samples/5/y", f"/samples/{len(samples) - 1}/t"]
    assert "must fit a float32" in found[0]["message"]
    assert client.get(url(dem), headers=auth).json()["data"] == []


def test_a_json_sample_past_float32s_range_and_units_too_long_come_in_one_answer(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    samples = [{"t": t, "x": x, "y": y} for t, x, y in walk().tolist()]
    samples[5]["x"] = 1e39
    body = {"protocol": "standing", "units": "u" * 17, "samples": samples}
    found = errors(client.post(url(dem), json=body, headers=auth))
    assert [e["pointer"] for e in found] == ["/units", "/samples/5/x"]
    assert "must fit a float32" in found[1]["message"]
    assert client.get(url(dem), headers=auth).json()["data"] == []


def test_a_csv_cell_past_float32s_range_is_a_422_naming_its_sample_and_line(
    client: TestClient, auth: dict[str, str]
) -> None:
    text = table(["t", "x", "y"], walk()).decode().splitlines()
    text[6] = "0.05,1e39,0"
    (error,) = errors(upload(client, auth, "trial.csv", "\n".join(text).encode()))
    assert error["pointer"] == "/samples/5/x"
    assert "must fit a float32" in error["message"] and "CSV line 7" in error["message"]


# ------------------------------------------------------------------ CSVs as plate software writes them


@pytest.mark.parametrize(
    ("delimiter", "header"),
    [
        ("\t", ["Time[s]", "COPx[cm]", "COPy[cm]"]),
        (";", ["t (s)", "x (cm)", "y (cm)"]),
        (",", ["time", "copx", "COPY"]),
    ],
    ids=["tab, brackets", "semicolon, parentheses", "comma, aliases"],
)
def test_a_tab_or_semicolon_csv_with_aliases_and_units_is_read(
    client: TestClient, auth: dict[str, str], delimiter: str, header: list[str]
) -> None:
    rows = walk()
    out = created(upload(client, auth, "trial.txt", table(header, rows, delimiter)))
    assert out["n_samples"] == len(rows) and out["format"] == "csv"
    sway = created(client.get(f"/v1/recordings/{out['id']}/sway", headers=auth), 200)
    assert sway["units"] == ("cm" if "[" in header[1] or "(" in header[1] else None)


def test_a_header_that_names_no_columns_says_which_columns_and_delimiter_it_read(
    client: TestClient, auth: dict[str, str]
) -> None:
    (error,) = errors(upload(client, auth, "trial.txt", table(["t", "x", "y"], walk(), "|")))
    assert "missing t, x, y" in error["message"]
    assert "read the columns 't|x|y' (delimiter: comma)" in error["message"]


def test_units_that_contradict_the_csv_header_are_a_422_at_units(
    client: TestClient, auth: dict[str, str]
) -> None:
    data = table(["t", "COPx[cm]", "COPy[cm]"], walk(), "\t")
    (error,) = errors(upload(client, auth, "trial.txt", data, units="mm"))
    assert error["pointer"] == "/units" and "'cm'" in error["message"]
    assert created(upload(client, auth, "trial.txt", data, units="centimetres"))["n_samples"] == 400


def test_a_time_column_not_in_seconds_is_a_422(client: TestClient, auth: dict[str, str]) -> None:
    (error,) = errors(upload(client, auth, "trial.csv", table(["t (ms)", "x", "y"], walk())))
    assert error["pointer"] == "/file" and "'ms'" in error["message"]


def test_a_raw_hbedb_file_uploaded_as_standing_gives_the_authors_coparea(
    client: TestClient, auth: dict[str, str]
) -> None:
    """The data set's own file, unmodified (tab-separated, forces, moments and the COP in cm): its COP
    columns are read, in the header's unit."""
    folder = shared_data("hbedb")
    with (folder / "reference-descriptors.tsv").open() as fh:
        reference = next(row for row in csv.DictReader(fh, delimiter="\t") if row["Trial"] == "BDS00001")
    out = created(upload(client, auth, "BDS00001.txt", (folder / "BDS00001.txt").read_bytes()))
    assert out["format"] == "csv" and out["n_samples"] == 6000 and "plate" not in out["settings"]
    sway = created(client.get(f"/v1/recordings/{out['id']}/sway", headers=auth), 200)
    assert sway["units"] == "cm"
    assert sway["descriptors"]["area95"] == pytest.approx(float(reference["COParea"]), rel=1e-6)


def test_plate_options_for_a_csv_with_cop_columns_are_a_422_saying_the_cop_wins(
    client: TestClient, auth: dict[str, str]
) -> None:
    header = ["Time[s]", "Fx[N]", "Fy[N]", "Fz[N]", "Mx[Nm]", "My[Nm]", "Mz[Nm]", "COPx[cm]", "COPy[cm]"]
    rows = np.column_stack(
        [walk()[:, 0], np.zeros((400, 2)), np.full(400, 600.0), np.zeros((400, 3)), walk()[:, 1:]]
    )
    (error,) = errors(upload(client, auth, "trial.txt", table(header, rows, "\t"), plate={"min_fz": 10}))
    assert error["pointer"] == "/plate" and "COP columns are read as they are" in error["message"]


def test_a_plate_csv_takes_its_moment_unit_from_the_header_and_refuses_one_it_contradicts(
    client: TestClient, auth: dict[str, str]
) -> None:
    fz = 600.0
    moments = np.column_stack([COP[:, 1] * 1000 * fz, -COP[:, 0] * 1000 * fz, np.zeros(len(COP))])
    rows = np.column_stack([np.zeros((len(COP), 2)), np.full(len(COP), fz), moments])
    data = table(["Fx[N]", "Fy[N]", "Fz[N]", "Mx[N.mm]", "My[N.mm]", "Mz[N.mm]"], rows, ";")
    out = created(upload(client, auth, "plate.csv", data, plate={"rate_hz": 50}))
    assert out["format"] == "forces" and out["settings"]["plate"]["moment_unit"] == "Nmm"
    assert out["settings"]["bounds"]["x_min"] == pytest.approx(COP[:, 0].min(), abs=1e-6)
    contradicted = upload(client, auth, "plate.csv", data, plate={"rate_hz": 50, "moment_unit": "Nm"})
    assert errors(contradicted)[0]["pointer"] == "/plate/moment_unit"
    (error,) = errors(upload(client, auth, "plate.csv", data, plate={"rate_hz": 50}, units="cm"))
    assert error["pointer"] == "/units" and "Nmm" in error["message"]


# ------------------------------------------------------------------ a C3D's own unit


def test_a_c3d_with_units_other_than_its_own_or_metres_is_a_422_at_units(
    client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    data = c3d_bytes(tmp_path, COP)
    (error,) = errors(upload(client, auth, "trial.c3d", data, units="cm"))
    assert error["pointer"] == "/units" and "POINT:UNITS 'mm'" in error["message"]
    for units in ("mm", "m"):  # the file's own unit, or the metres its COP is stored in
        out = created(upload(client, auth, "trial.c3d", data, units=units))
        assert out["format"] == "c3d" and out["settings"]["units"] == "m"


def test_an_error_of_the_whole_csv_points_at_its_file_part(client: TestClient, auth: dict[str, str]) -> None:
    (error,) = errors(upload(client, auth, "trial.csv", b"a,b,c\n1,2,3\n"))
    assert error["pointer"] == "/file" and "missing t, x, y" in error["message"]


@pytest.mark.parametrize(
    ("change", "pointer"),
    [
        ({"sample_rate": 100}, "/sample_rate"),
        ({"samples": [{"t": 0, "x": 0, "y": 0, "z": 1}]}, "/samples/0/z"),
    ],
)
def test_a_field_a_recording_does_not_know_is_a_422_at_it(
    client: TestClient, auth: dict[str, str], change: dict, pointer: str
) -> None:
    dem = make_demonstrator(client, auth)
    samples = [{"t": t, "x": x, "y": y} for t, x, y in walk().tolist()]
    body = {"protocol": "standing", "samples": samples} | change
    found = errors(client.post(url(dem), json=body, headers=auth))
    assert [e["pointer"] for e in found] == [pointer] and "misspelt" in found[0]["message"]
    (error,) = errors(upload(client, auth, "trial.csv", table(["t", "x", "y"], walk()), colour="red"))
    assert error["pointer"] == "/colour"


# ------------------------------------------------------------------ names


def test_a_file_uploaded_without_a_name_is_named_after_its_file_and_a_given_name_is_kept(
    client: TestClient, auth: dict[str, str]
) -> None:
    data = table(["t", "x", "y"], walk())
    unnamed = upload(client, auth, "C:\\plate exports\\BDS00012.csv", data, units="cm")
    assert created(unnamed)["name"] == "BDS00012.csv"  # the file's name, without the client's folders
    named = upload(client, auth, "trial.csv", data, units="cm", name="eyes open, firm")
    assert created(named)["name"] == "eyes open, firm"
