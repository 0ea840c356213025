"""Tests for the test-bed parameter file and its loader (bscomp.systems.parameters)."""

import math

import pytest

from bscomp.systems.parameters import DATA_DIR, flatten, get_value, load_parameters


@pytest.fixture(scope="module")
def params():
    return load_parameters()


def test_bundled_file_exists():
    assert (DATA_DIR / "fadal_vmc2216_x.toml").is_file()


def test_groups_present(params):
    for group in ("screw", "nut", "table", "rotor", "coupling", "bearings", "guideways", "screw_nut",
                  "electrical", "control", "friction_backlash", "damping", "reference_results"):
        assert group in params, group


def test_every_entry_has_value_unit_source(params):
    entries = flatten(params)
    assert len(entries) > 150
    for key, entry in entries.items():
        assert {"value", "unit", "source"} <= set(entry), key
        assert isinstance(entry["unit"], str) and isinstance(entry["source"], str), key
        assert entry["source"].strip(), key


def test_choices_are_documented(params):
    # every unpublished default carries a note saying it is a choice
    for key in ("coupling.attach_position", "bearings.b1_position", "bearings.b2_position", "table.travel",
                "table.nut_position_L", "screw.motor_end", "damping.zeta_other"):
        entry = params
        for part in key.split("."):
            entry = entry[part]
        assert entry["note"].startswith("CHOICE"), key


def test_thesis_numbers(params):
    assert get_value(params, "reference_results.J") == pytest.approx(8.55e-3)
    assert get_value(params, "control.J") == pytest.approx(8.55e-3)
    assert get_value(params, "coupling.kT") == pytest.approx(3938.0)
    assert get_value(params, "coupling.kT") == pytest.approx(3.94e3, rel=2e-3)  # Table 3.1
    assert get_value(params, "rotor.Izz") == pytest.approx(5.98e-3)
    assert get_value(params, "table.mass") == pytest.approx(250.0)
    assert get_value(params, "nut.mass") == pytest.approx(1.49)
    assert get_value(params, "bearings.b1_k_axial") == pytest.approx(2.70e8)
    assert get_value(params, "bearings.b2_k_radial") == pytest.approx(4e7)
    assert get_value(params, "screw_nut.N_ball") == 100
    assert get_value(params, "screw_nut.k_ball") == pytest.approx(20.7e6)
    assert get_value(params, "electrical.K_a") == pytest.approx(6.4898)
    assert get_value(params, "electrical.K_t") == pytest.approx(0.4769)
    assert get_value(params, "friction_backlash.B_viscous") == pytest.approx(12673.0)
    assert get_value(params, "reference_results.free_free_axial_measured") == [2493.0, 2914.0, 2532.0]
    assert get_value(params, "reference_results.table41_fn1") == [109.51, 117.69, 133.82]


def test_r_g_from_pitch(params):
    p = get_value(params, "screw.pitch")
    assert p == pytest.approx(0.010)
    r_g = get_value(params, "control.r_g")
    assert r_g == pytest.approx(p / (2 * math.pi), rel=1e-9)
    assert r_g == pytest.approx(1.59e-3, rel=2e-3)  # as printed in Sec 4.2.1


def test_alpha_from_pitch_diameter(params):
    p = get_value(params, "screw.pitch")
    d_p = get_value(params, "screw.pitch_diameter")
    alpha = get_value(params, "screw_nut.alpha")
    assert math.degrees(math.atan(p / (math.pi * d_p))) == pytest.approx(4.549, abs=1e-3)
    assert math.degrees(alpha) == pytest.approx(4.55, abs=1e-3)


def test_consistency_relations(params):
    r_g = get_value(params, "control.r_g")
    # B (Sec 4.2.1) is the guideway viscous coefficient (Table 5.2) seen from the motor
    assert get_value(params, "guideways.viscous_coefficient") * r_g**2 == pytest.approx(
        get_value(params, "control.B"), rel=2e-3)
    # Eq B.1 with the measured 805 Hz gives k_T to within rounding
    J1, J2 = get_value(params, "coupling.J1"), get_value(params, "coupling.J2")
    f = get_value(params, "coupling.measured_frequency")
    assert (2 * math.pi * f) ** 2 * J1 * J2 / (J1 + J2) == pytest.approx(
        get_value(params, "coupling.kT"), rel=3e-3)
    # Eq 3.41: nut axial stiffness from k_ball (oversize-ball preload)
    a, b = get_value(params, "screw_nut.alpha"), get_value(params, "screw_nut.beta")
    k_ax = 2 * get_value(params, "screw_nut.N_ball") * get_value(params, "screw_nut.k_ball") \
        * math.cos(a) ** 2 * math.cos(b) ** 2
    assert k_ax == pytest.approx(get_value(params, "screw_nut.k_axial"), rel=1e-3)
    # Table B.1 sections: 47 elements, ~921 mm
    secs = params["screw"]["sections"]
    assert sum(s["n_elements"]["value"] for s in secs.values()) == get_value(params, "screw.n_elements")
    total = sum(s["length"]["value"] for s in secs.values())
    assert total == pytest.approx(get_value(params, "screw.total_length"), abs=1e-3)
    # nut positions stay on the thread and L is farther from the thrust bearing than R
    lo = secs["A"]["length"]["value"] + secs["B"]["length"]["value"]
    hi = lo + secs["C"]["length"]["value"]
    half = get_value(params, "nut.length") / 2
    for k in ("L", "C", "R"):
        x = get_value(params, f"table.nut_position_{k}")
        assert lo + half - 1e-9 <= x <= hi - half + 1e-9
    b1 = get_value(params, "bearings.b1_position")
    assert b1 - get_value(params, "table.nut_position_L") > b1 - get_value(params, "table.nut_position_R")
    # root diameter default is Table B.1's, and the mass diameter is larger (Eq 3.1)
    assert get_value(params, "screw.root_diameter") == pytest.approx(0.0355)
    assert get_value(params, "screw.equivalent_diameter") > get_value(params, "screw.root_diameter")


def test_rigid_body_inertia_close_to_thesis(params):
    """Rotor + jaws + screw (mass diameter d_e) + translating mass * r_g^2 vs J = 8.55e-3."""
    rho = get_value(params, "screw.material.density")
    j_screw = 0.0
    for name, s in params["screw"]["sections"].items():
        d_o = params["screw"]["equivalent_diameter"]["value"] if name == "C" else s["outer_diameter"]["value"]
        d_i = s["inner_diameter"]["value"]
        j_screw += rho * math.pi * (d_o**4 - d_i**4) / 32 * s["length"]["value"]
    r_g = get_value(params, "control.r_g")
    J = (get_value(params, "rotor.Izz") + get_value(params, "coupling.J1") + get_value(params, "coupling.J2")
         + j_screw + (get_value(params, "table.mass") + get_value(params, "nut.mass")) * r_g**2)
    assert J == pytest.approx(get_value(params, "reference_results.J"), rel=0.02)


def test_get_value_errors(params):
    with pytest.raises(KeyError):
        get_value(params, "screw.no_such")
    with pytest.raises(KeyError):
        get_value(params, "screw.sections")


def test_missing_field_raises_naming_file_and_key(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('[coupling]\nkT = { value = 3938.0, unit = "N*m/rad" }\n')
    with pytest.raises(ValueError, match=r"bad\.toml.*coupling\.kT.*source"):
        load_parameters(f)


def test_missing_value_in_nested_group_raises(tmp_path):
    f = tmp_path / "bad2.toml"
    f.write_text('[screw.sections.A]\nlength = { unit = "m", source = "Table B.1" }\n')
    with pytest.raises(ValueError, match=r"bad2\.toml.*screw\.sections\.A\.length.*value"):
        load_parameters(str(f))


def test_bare_value_and_unknown_field_raise(tmp_path):
    f = tmp_path / "bare.toml"
    f.write_text("[nut]\nmass = 1.49\n")
    with pytest.raises(ValueError, match=r"bare\.toml.*nut\.mass"):
        load_parameters(f)
    g = tmp_path / "unknown.toml"
    g.write_text('[nut]\nmass = { value = 1.49, unit = "kg", source = "B.2", nte = "typo" }\n')
    with pytest.raises(ValueError, match=r"unknown\.toml.*nut\.mass.*nte"):
        load_parameters(g)


def test_invalid_toml_and_missing_file(tmp_path):
    f = tmp_path / "broken.toml"
    f.write_text("[nut\n")
    with pytest.raises(ValueError, match="broken.toml"):
        load_parameters(f)
    with pytest.raises(FileNotFoundError):
        load_parameters(tmp_path / "absent.toml")


def test_chapter4_numbers_reproduce(params):
    """Eq 4.12 (with K_a K_t H_g) gives Eq 4.14; Eq 4.19-4.21 give Table 4.3."""
    v = lambda k: get_value(params, k)  # noqa: E731
    J, B = v("control.J"), v("control.B")
    gain = v("electrical.K_a") * v("electrical.K_t") * v("electrical.H_g")
    wn = 2 * math.pi * v("control.velocity_loop_fn")
    assert J * wn**2 / gain == pytest.approx(v("control.K_i"), rel=2e-4)
    K_v = (2 * v("control.velocity_loop_zeta") * wn * J - B) / gain
    assert K_v == pytest.approx(v("control.K_v"), rel=2e-4)
    Ts, w = v("control.T_s"), v("control.notch_omega_N")

    def pair(z):
        decay = math.exp(-z * w * Ts)
        return -2 * decay * math.cos(w * Ts * math.sqrt(1 - z * z)), decay**2

    n1, n2 = pair(v("control.notch_zeta_N"))
    d1, d2 = pair(v("control.notch_zeta_D"))
    kn = (1 + d1 + d2) / (1 + n1 + n2)
    assert [n1, n2, d1, d2, kn] == pytest.approx(v("control.notch_coefficients"), abs=1.5e-4)


def test_write_variant_changes_only_the_named_values_and_keeps_their_sources(tmp_path, params):
    from bscomp.systems.parameters import write_variant

    changes = {"table.mass": 450.0, "coupling.kT": 45940.0, "screw.sections.C.n_elements": 30}
    path = write_variant(changes, tmp_path / "other.toml")
    other = load_parameters(path)
    base, new = flatten(params), flatten(other)
    assert set(base) == set(new)
    assert {k for k in base if base[k]["value"] != new[k]["value"]} == set(changes)
    for k, v in changes.items():
        assert new[k]["value"] == v and type(new[k]["value"]) is type(v)      # 30 stays an int (element count)
        assert new[k]["source"] == base[k]["source"] and new[k]["unit"] == base[k]["unit"]
    text = path.read_text()
    assert "# variant: was 250.0" in text and "# variant: was 3938.0" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.toml"]        # no temporary file left


def test_write_variant_names_a_key_it_cannot_find(tmp_path):
    from bscomp.systems.parameters import write_variant

    with pytest.raises(KeyError, match="'table.weight'"):
        write_variant({"table.weight": 1.0}, tmp_path / "bad.toml")
    with pytest.raises(KeyError, match="'screw.sections'"):              # a group, not an entry
        write_variant({"screw.sections": 1.0}, tmp_path / "bad.toml")
    assert not (tmp_path / "bad.toml").exists()                           # nothing written
