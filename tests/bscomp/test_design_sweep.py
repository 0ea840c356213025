"""Design sweeps on any executor: the same table serially, on local processes and on a Dask cluster;
the compiled evaluator against full rebuilds; named errors."""

import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from bscomp import System
from bscomp.design_sweep import SweepTable, design_study
from bscomp.errors import UnknownNameError, UsageError
from bscomp.linear import modes, position_sweep
from bscomp.model import ModelSpec
from bscomp.systems.validation_drive import validation_drive
from bscomp.validate.candidates import default_candidates
from bscomp.validate.diagnostics import diagnose
from bscomp.validate.synthetic import generate

MOVING = ModelSpec("testbed_axial_torsional", {"nut_joint": "moving"})
GRID = {"b1.k_axial": [2.0e8, 3.4e8], "coupling.k_T": [3000.0, 4500.0], "sn.z0": [0.2, 0.5, 0.7]}


@pytest.fixture(scope="module")
def serial():
    return design_study(MOVING, GRID, executor="serial")


@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed", reason="the cluster test needs dask[distributed] "
                                                           "(pip install -e '.[cluster]')")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                       dashboard_address=None, silence_logs=40)
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_table_layout_and_grid_order(serial):
    assert serial.columns[:3] == list(GRID) and "f1" in serial.columns and "zeta6" in serial.columns
    assert len(serial) == 12
    np.testing.assert_array_equal(serial["sn.z0"][:3], GRID["sn.z0"])           # last name fastest
    assert serial.stats["kinds"] == {"b1.k_axial": "affine", "coupling.k_T": "affine", "sn.z0": "tangent"}
    assert np.all(np.diff(serial["f1"][:3]) > 0)        # first axial mode rises as the nut nears the thrust pair
    assert np.all(serial["f2"] > serial["f1"])


def test_variants_match_a_full_rebuild(serial):
    """The compiled evaluator (affine sensitivities + nut tangent + one eigh) is the rebuilt model."""
    for k in (0, 7, 11):
        row = serial.rows()[k]
        md = modes(MOVING.with_overrides({n: row[n] for n in GRID}).system())
        el = ~md.rigid_body
        np.testing.assert_allclose([row[f"f{i + 1}"] for i in range(6)], md.frequencies[el][:6], rtol=1e-8)
        # modal ratios vs the damped-pole ratios of modes(): equal to O(zeta^2)
        np.testing.assert_allclose([row[f"zeta{i + 1}"] for i in range(2)], md.damping[el][:2], rtol=1e-4)


def test_local_processes_give_the_serial_table(serial):
    with ProcessPoolExecutor(max_workers=2) as pool:
        par = design_study(MOVING, GRID, executor=pool, chunksize=3)
    assert par.columns == serial.columns
    np.testing.assert_allclose(par.data, serial.data, rtol=1e-12)


def test_dask_cluster_gives_the_serial_table(dask_client):
    # the lumped drive keeps the workers' set-up short; the evaluator is the one checked on the test bed above
    grid = {"coupling.c": [2000.0, 3938.0, 8000.0], "table.m": [200.0, 300.0], "axial.c": [5e7, 1e8]}
    serial = design_study("small_drive", grid, executor="serial", n_modes=2)
    tab = design_study("small_drive", grid, executor=dask_client.get_executor(), chunksize=3, n_modes=2)
    assert tab.columns == serial.columns and tab.stats["executor"] == "ClientExecutor"
    assert serial.stats["kinds"] == {"coupling.c": "affine", "table.m": "affine", "axial.c": "affine"}
    np.testing.assert_allclose(tab.data, serial.data, rtol=1e-12)


def test_position_sweep_on_the_dask_executor(dask_client):
    xs = [0.25, 0.6]
    local = position_sweep("testbed_axial_torsional", xs, method="rebuild", n_modes=3)
    remote = position_sweep("testbed_axial_torsional", xs, n_modes=3, executor=dask_client.get_executor())
    np.testing.assert_allclose(remote.frequencies, local.frequencies, rtol=1e-10)


def test_explicit_variants_frf_and_build_keyword():
    variants = [{"nut_position": 0.3, "table.m": 250.0}, {"nut_position": 0.6, "table.m": 300.0}]
    tab = design_study("testbed_axial_torsional", variants, analysis="frf", inputs=["amp.u"], outputs=["table.a"],
                       freqs=np.linspace(50, 400, 351), executor="serial")
    assert tab.stats["kinds"]["nut_position"] == "direct"
    assert tab.columns == ["nut_position", "table.m", "peak[table.a/amp.u]", "f_peak[table.a/amp.u]"]
    for k, v in enumerate(variants):
        md = modes(ModelSpec("testbed_axial_torsional", v).system())
        f1 = md.frequencies[~md.rigid_body][0]
        assert abs(tab["f_peak[table.a/amp.u]"][k] - f1) < 0.03 * f1      # the peak sits on the first mode


def test_callable_analysis_and_exports(tmp_path):
    tab = design_study("small_drive", {"coupling.c": [3000.0, 6000.0]}, analysis=_first_mode, executor="serial")
    assert tab.columns == ["coupling.c", "f1_rebuilt"] and tab["f1_rebuilt"][1] > tab["f1_rebuilt"][0]
    tab.to_csv(tmp_path / "t.csv")
    back = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(back, tab.data, rtol=1e-15)
    d = json.loads(tab.to_json(tmp_path / "t.json"))
    assert d["columns"] == tab.columns and len(d["rows"]) == 2
    pd = pytest.importorskip("pandas", reason="to_pandas needs pandas")
    df = tab.to_pandas()
    assert isinstance(df, pd.DataFrame) and list(df.columns) == tab.columns
    np.testing.assert_array_equal(df.to_numpy(), tab.data)


def _first_mode(spec):
    md = modes(spec.system())
    return {"f1_rebuilt": float(md.frequencies[~md.rigid_body][0])}


def test_grid_map():
    tab = SweepTable(columns=["a", "b", "f1"], data=np.array([[1, 10, 5.0], [2, 10, 6.0], [1, 20, 7.0], [2, 20, 8.0]]),
                     parameters=["a", "b"])
    xs, ys, Z = tab.grid("a", "b", "f1")
    np.testing.assert_array_equal(Z, [[5.0, 6.0], [7.0, 8.0]])


def test_named_errors():
    with pytest.raises(UnknownNameError, match="cannot travel"):
        design_study(System("x"), {"a.b": [1.0]})
    with pytest.raises(UsageError, match="analysis"):
        design_study("small_drive", {"table.m": [1.0]}, analysis="bode", executor="serial")
    with pytest.raises(UsageError, match="same parameters"):
        design_study("small_drive", [{"table.m": 1.0}, {"coupling.c": 2.0}], executor="serial")
    with pytest.raises(UsageError, match="executor"):
        design_study("small_drive", {"table.m": [200.0]}, executor=42)
    with pytest.raises(UnknownNameError, match="no parameter"):
        design_study("small_drive", {"table.mass": [200.0]}, executor="serial")


def test_diagnose_candidate_fits_on_the_dask_executor(dask_client):
    """diagnose(executor=) fits the candidates on the workers and reaches the serial diagnosis."""
    data = generate(hidden={"nut_table_joint": {}}, seed=3)
    cands = [c for c in default_candidates() if c.name in ("nut_table_joint", "guideway_friction")]
    kw = dict(candidates=cands, max_effects=1, n_refine=1, n_scan=5, n_screen=2)
    serial = diagnose("validation_drive", data.datasets, **kw)
    remote = diagnose("validation_drive", data.datasets, executor=dask_client.get_executor(), **kw)
    assert [a.name for a in remote.accepted] == [a.name for a in serial.accepted] == ["nut_table_joint"]
    for a, b in zip(remote.accepted, serial.accepted):
        assert a.values == pytest.approx(b.values, rel=1e-10)
    assert [e for _, e in remote.staircase] == pytest.approx([e for _, e in serial.staircase], rel=1e-10)
    with pytest.raises(UnknownNameError, match="cannot travel"):
        diagnose(validation_drive(), data.datasets, executor=dask_client.get_executor(), **kw)
