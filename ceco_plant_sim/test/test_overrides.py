"""ceco_core.overrides: field overrides of frozen parameter dataclasses, nested parts by dotted name."""

import dataclasses

import pytest

from ceco_core.cabin_comfort import ComfortParams
from ceco_core.overrides import check_overrides, with_overrides
from ceco_plant_sim.plant_params import PlantParams


def test_nested_and_flat_fields_are_replaced_and_the_rest_kept():
    base = ComfortParams()
    new = with_overrides(
        base,
        {
            'air.jet_body_fraction': 0.2,
            'solar.f_bes': 0.75,
            'met': 1.4,
            'radiant.f_interior': 0.44,
            'radiant.f_shell': 0.34,
        },
    )
    assert (new.air.jet_body_fraction, new.solar.f_bes, new.met) == (0.2, 0.75, 1.4)
    assert (new.radiant.f_interior, new.radiant.f_shell, new.radiant.f_glass) == (0.44, 0.34, 0.22)
    assert new.air.c_room == base.air.c_room and new.solar.asw == base.solar.asw and new.clo == base.clo
    assert base.air.jet_body_fraction == 0.1  # the original is untouched (frozen copies)
    assert with_overrides(base, {}) is base and with_overrides(base, None) is base
    p = with_overrides(PlantParams(), {'c_int_jpk': 60000, 'n_occupants': 2})
    assert p.c_int_jpk == 60000.0 and isinstance(p.c_int_jpk, float) and p.n_occupants == 2
    assert dataclasses.replace(p, c_int_jpk=90000.0, n_occupants=1) == PlantParams()


@pytest.mark.parametrize(
    'overrides, message',
    [
        ({'a2': 0.25}, r'ComfortParams\.a2: no such field \(fields: air, clo, met'),
        ({'air.jet_bodyfraction': 0.2}, r'ComfortParams\.air\.jet_bodyfraction: no such field'),
        ({'met.x': 1.0}, r'ComfortParams\.met\.x: ComfortParams\.met is a float, not a part with fields'),
        ({'air': 1.0}, r'ComfortParams\.air is a OccupantAirParams: override its fields by dotted name'),
        ({'air.dr_in_jet': 1}, r'ComfortParams\.air\.dr_in_jet must be a bool'),
        ({'solar.f_bes': True}, r'ComfortParams\.solar\.f_bes must be a finite number'),
        ({'solar.f_bes': float('nan')}, r'ComfortParams\.solar\.f_bes must be a finite number'),
        ({'solar.f_bes': '0.5'}, r'ComfortParams\.solar\.f_bes must be a finite number'),
        ({'solar.f_bes': 1.5}, r'SolarParams\.f_bes must be a finite number in \[0\.0, 1\.0\]'),
        ({'radiant.f_glass': 0.3}, r'RadiantParams\.f_interior: the angle factors must sum to 1'),
        ({'': 1.0}, r'override names must be non-empty strings'),
    ],
)
def test_errors_name_the_field(overrides, message):
    with pytest.raises(ValueError, match=message):
        check_overrides(ComfortParams(), overrides)


def test_plant_errors_name_the_field():
    with pytest.raises(ValueError, match=r'PlantParams\.refrigerant: a field of type str cannot be overridden'):
        with_overrides(PlantParams(), {'refrigerant': 'R134a'})
    with pytest.raises(ValueError, match=r'PlantParams with overrides .*c_int_jpk'):
        with_overrides(PlantParams(), {'c_int_jpk': -1.0})
    with pytest.raises(ValueError, match='must be a mapping'):
        with_overrides(PlantParams(), [('c_int_jpk', 1.0)])
