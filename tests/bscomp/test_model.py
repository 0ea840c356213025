"""bscomp.model: the one way to turn a name, a .py path, a build function, a System, a Dae or a ModelSpec
into what an analysis needs -- and every analysis accepting all of them alike."""

import pickle
import textwrap

import numpy as np
import pytest

import bscomp
from bscomp.errors import UnknownNameError
from bscomp.model import ModelSpec, as_dae, as_system, spec_of, split_overrides
from bscomp.systems import small_drive

FILE = textwrap.dedent('''
    from bscomp.systems import small_drive


    def build(table_mass=None):
        s = small_drive()
        if table_mass is not None:
            s.set("table.m", table_mass)
        return s
''')


@pytest.fixture()
def drive_file(tmp_path):
    path = tmp_path / "my_drive.py"
    path.write_text(FILE)
    return str(path)


def test_spec_is_picklable_hashable_and_rebuilds_the_same_drive():
    spec = ModelSpec("small_drive", {"table.m": 50.0})
    again = pickle.loads(pickle.dumps(spec))
    assert again == spec and hash(again) == hash(spec)
    assert again.system().get("table.m") == pytest.approx(50.0)
    assert spec.with_overrides({"table.m": 60.0}).system().get("table.m") == pytest.approx(60.0)


def test_overrides_split_into_build_keywords_and_parameters():
    assert split_overrides({"nut_position": 0.3, "coupling.k_T": 1e4}) == ({"nut_position": 0.3},
                                                                            {"coupling.k_T": 1e4})


def test_every_form_gives_the_same_modes(drive_file):
    """Name, path (with a build keyword), build function, spec, System and Dae: identical frequencies."""
    ref = bscomp.modes(small_drive()).frequencies
    forms = ["small_drive", drive_file, small_drive, ModelSpec("small_drive"), small_drive(),
             bscomp.flatten(small_drive())]
    for form in forms:
        np.testing.assert_allclose(bscomp.modes(form).frequencies, ref, rtol=1e-12, err_msg=repr(form))
    keyword = bscomp.modes(drive_file, params={"table_mass": 200.0}).frequencies      # a build keyword
    dotted = bscomp.modes("small_drive", params={"table.m": 200.0}).frequencies       # a parameter override
    np.testing.assert_allclose(keyword, dotted, rtol=1e-12)
    assert abs(keyword[1] - ref[1]) > 1.0


def test_frf_accepts_every_form(drive_file):
    f = [5.0, 50.0]
    ref = bscomp.frf(small_drive(), "motor.tau", "rotor.w", f).H
    for form in ("small_drive", drive_file, ModelSpec("small_drive"), small_drive):
        np.testing.assert_allclose(bscomp.frf(form, "motor.tau", "rotor.w", f).H, ref, rtol=1e-12)


def test_as_dae_flattens_once_and_reuses_a_dae():
    dae = as_dae("small_drive")
    assert as_dae(dae) is dae
    assert as_system(dae).name == "small_drive"


def test_bad_models_are_named():
    with pytest.raises(UnknownNameError, match="no_such_drive"):
        as_system("no_such_drive")
    with pytest.raises(UnknownNameError, match="cannot use int"):
        as_system(42)
    with pytest.raises(UnknownNameError, match="build keywords"):
        as_system(small_drive(), {"nut_position": 0.3})
    with pytest.raises(UnknownNameError, match="cannot travel to a worker"):
        spec_of(small_drive())
    with pytest.raises(UnknownNameError, match="not a bscomp.System"):
        as_system(lambda: 3)
