"""The pint-free reading of common quantities (copdea_fem/units.py, issue 25)."""

import subprocess
import sys
from pathlib import Path

import pint
import pytest

from copdea_fem.study import StudyError, convert_quantity, load_study
from copdea_fem.units import LABEL_UNITS, UNITS, fast_to_si

ROOT = Path(__file__).resolve().parents[2]
MAGNITUDES = ["16", "35.5", "1.5e-3", "-2", "0.1", "228.5", ".5", "3.", "123456789",
              "0.3333333333333333", "2.2e-16", "-731.2715117751975", "1E3", "+4"]


@pytest.fixture(scope="module")
def registry():
    return pint.UnitRegistry()


@pytest.mark.parametrize("symbol", sorted(UNITS))
def test_every_table_entry_is_bitwise_pint(registry, symbol):
    unit = UNITS[symbol][0]
    for magnitude in MAGNITUDES:
        text = f"{magnitude} {symbol}"
        value = fast_to_si(text, unit)
        assert value is not None, text
        assert value == float(registry.Quantity(text).to(unit).magnitude), text


def test_what_the_table_cannot_say_goes_to_pint():
    assert fast_to_si("16 kV", "m") is None             # another dimension: pint words it
    assert fast_to_si("16 millimeter", "m") is None     # other spelling
    assert fast_to_si("(1 + 2) mm", "m") is None        # an expression
    assert convert_quantity("geometry.x", "16 millimeter", "m") == pytest.approx(0.016)
    assert convert_quantity("geometry.x", "1 cm + 2 mm", "m") == pytest.approx(0.012)
    with pytest.raises(StudyError, match="wrong unit, expected a quantity in m"):
        convert_quantity("geometry.x", "16 kV", "m")
    with pytest.raises(StudyError, match="is not allowed"):
        convert_quantity("geometry.x", "-16 mm", "m", minimum=0)


def test_a_study_of_common_units_loads_without_importing_pint():
    code = ("import sys; from copdea_fem.study import load_study; "
            f"s = load_study({str(ROOT / 'studies' / 'g1_z16_v2.yaml')!r}, "
            "{'load.voltage': '1.5 kV', 'geometry.frame': 'baffle'}); "
            "print(s.get('load.voltage'), 'pint' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.split()
    assert out == ["1500.0", "False"]


def test_the_study_values_equal_pints():
    """Every key of the shipped studies reads to the value pint gives (bitwise)."""
    import copdea_fem.study.keys as keys_module

    fast = load_study(ROOT / "studies" / "g1_z16_v2.yaml").values
    original = keys_module.fast_to_si
    keys_module.fast_to_si = lambda text, unit: None
    try:
        slow = load_study(ROOT / "studies" / "g1_z16_v2.yaml").values
    finally:
        keys_module.fast_to_si = original
    assert fast == slow


# --- the unit labels of measurement files (copdea_fem.units.fast_label_to_si, issue 42) ----

#: Labels real exports write (the samples of shared/realdata, PSV, Test.Lab, a shaker
#: controller) and a few more of the same kind.
LABELS = ["Hz", "m/s", "V", "N", "m", "s", "mm/s", "µm/s", "μm/s", "um", "m/s/V", "(m/s)/V",
          "m/s²", "m/s^2", "m/s**2", "(1/N)*(m/s²)", "m/s^2/N", "(m/s)/N", "m/N", "g", "g/N",
          "g²/Hz", "(m/s)²/Hz", "mV", "kN", "ms", "kHz", "1/s", "Pa", "kPa", "A", "m/s rms",
          "mm/s/V", "nm", "cm/s", "kg", "V/Pa", "m/s / V", " m/s "]


def _pint_only(label):
    """parse_unit_label as it reads a label without the table: pint alone."""
    import copdea_fem.measured.uff_units as uff_units

    original = uff_units.fast_label_to_si
    uff_units.fast_label_to_si = lambda text: None
    uff_units.parse_unit_label.cache_clear()
    try:
        return uff_units.parse_unit_label(label)
    finally:
        uff_units.fast_label_to_si = original
        uff_units.parse_unit_label.cache_clear()


@pytest.mark.parametrize("label", LABELS)
def test_a_common_label_reads_as_pint_reads_it(label):
    from copdea_fem.measured.uff_units import parse_unit_label

    slow = _pint_only(label)
    parse_unit_label.cache_clear()
    fast = parse_unit_label(label)
    assert slow is not None and fast is not None, label
    assert fast.factor == pytest.approx(slow.factor, rel=1e-15), label
    assert fast.dimensions == slow.dimensions, label


@pytest.mark.parametrize("label", sorted(LABEL_UNITS))
def test_every_label_symbol_is_pints(registry, label):
    factor, dimensions = LABEL_UNITS[label]
    base = (1.0 * registry.parse_expression(label)).to_base_units()
    assert factor == float(base.magnitude) and dimensions == dict(base.dimensionality)


@pytest.mark.parametrize("text", ["in/s", "m s", "2 m", "(m/s", "m/s)", "m**", "1", "m/m",
                                  "mg", "Nm", "m**1.5", "degC", "", "m/s/", "ft/s"])
def test_what_the_label_table_cannot_say_goes_to_pint(text):
    from copdea_fem.units import fast_label_to_si

    assert fast_label_to_si(text) is None, text


def test_a_common_label_is_read_without_importing_pint():
    code = ("import sys; from copdea_fem.measured.uff_units import parse_unit_label as p; "
            "print(p('(1/N)*(m/s²)').dimensions, p('g²/Hz').factor, 'pint' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == "{'[mass]': -1} 96.17038422249999 False"
