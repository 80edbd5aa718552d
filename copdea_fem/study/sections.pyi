"""Type stub of :mod:`copdea_fem.study.sections`, made from ``SCHEMA`` by
``python -m copdea_fem.study --stubs`` (do not edit by hand)."""

from typing import Any

class PronyTerm:
    modulus_ratio: float
    relaxation_time: float
    def __init__(self, modulus_ratio: float, relaxation_time: float) -> None: ...

class Enclosure:
    kind: str
    depth: float
    radius: float
    vent_radius: float
    def __init__(self, kind: str, depth: float, radius: float, vent_radius: float) -> None: ...

class SegmentDrive:
    amplitude: float
    phase: float
    def __init__(self, amplitude: float = ..., phase: float = ...) -> None: ...

class ElectrodeSegment:
    name: str
    theta: tuple[float, float]
    r: tuple[float, float] | None
    drive: SegmentDrive
    def __init__(self, name: str, theta: Any, r: Any = ..., drive: Any = ...) -> None: ...
    def plain(self) -> dict[str, Any]: ...

class ThicknessTerm:
    order: int
    amplitude: float
    angle: float
    def __init__(self, order: int, amplitude: float, angle: float = ...) -> None: ...
    def plain(self) -> dict[str, Any]: ...

class PointMass:
    mass: float
    r: float
    theta: float
    def __init__(self, mass: float, r: float, theta: float = ...) -> None: ...
    def plain(self) -> dict[str, Any]: ...

class GeometrySection:
    outer_radius: float
    inner_radius: float
    frame: str
    frame_side: float
    frame_radius: float | None
    enclosure: str
    enclosure_depth: float | None
    enclosure_radius: float | None
    enclosure_vent_radius: float
    @property
    def enclosure_shape(self) -> Enclosure | None: ...
    def __init__(self, **values: Any) -> None: ...

class MembraneSection:
    thickness: float
    prestretch: float
    density: float
    relative_permittivity: float
    c10: float
    c20: float
    c01: float
    loss_factor: float
    rayleigh_alpha: float
    rayleigh_beta: float
    prony: tuple[PronyTerm, ...]
    prestretch_anisotropy: float
    prestretch_axis: float
    thickness_variation: tuple[ThicknessTerm, ...]
    def __init__(self, **values: Any) -> None: ...

class DiscSection:
    mass: float
    motion: str
    def __init__(self, **values: Any) -> None: ...

class SpringSection:
    stiffness: float
    mass: float
    length: float
    def __init__(self, **values: Any) -> None: ...

class LoadSection:
    z: float
    voltage: float
    def __init__(self, **values: Any) -> None: ...

class AirSection:
    enabled: bool
    density: float
    sound_speed: float
    domain_radius: float | None
    pml_thickness: float | None
    outside: bool
    min_membrane_energy: float
    def __init__(self, **values: Any) -> None: ...

class MeshSection:
    membrane_size: float
    air_size: float | None
    grading: float
    order: int
    pressure_order: int
    curve_order: int
    symmetry: str
    engine: str
    def __init__(self, **values: Any) -> None: ...

class PrestressSection:
    z_steps: int
    voltage_steps: int
    max_cuts: int
    newton_tol: float
    max_newton_iter: int
    def __init__(self, **values: Any) -> None: ...

class EigenSection:
    f_min: float
    f_max: float
    max_modes: int
    backend: str
    max_damping_ratio: float
    residual_tol: float
    factor_memory_gb: float
    def __init__(self, **values: Any) -> None: ...

class OutputSection:
    directory: str | None
    paraview: bool
    plots: bool
    def __init__(self, **values: Any) -> None: ...

class ReducedSection:
    rings: int
    modes: str
    modes_json: str | None
    coupled_freq_p1: float | None
    coupled_freq_01: float | None
    coupled_freq_02: float | None
    pumping_added_mass: str
    damping_p1: float
    damping_01: float
    damping_02: float
    damping_higher: float
    scan_radii: int
    def __init__(self, **values: Any) -> None: ...

class ExcitationSection:
    amplitude: float
    f_start: float
    f_end: float
    duration: float
    sample_time: float
    def __init__(self, **values: Any) -> None: ...

class ResponseSection:
    method: str
    reduced_tol: float
    modal_band: float
    microphone_distance: float
    microphones: str
    peaks: int
    def __init__(self, **values: Any) -> None: ...

class EffectsSection:
    stiffness_scale: float
    maxwell_scale: float
    air_added_mass: str
    air_mass_scale: float
    viscoelastic_strength: float
    viscoelastic_time: float
    def __init__(self, **values: Any) -> None: ...

class ElectrodesSection:
    segments: tuple[ElectrodeSegment, ...]
    def __init__(self, **values: Any) -> None: ...

class ImperfectionsSection:
    point_masses: tuple[PointMass, ...]
    def __init__(self, **values: Any) -> None: ...

LIST_ITEM_CLASSES: dict[tuple[str, str], type]
SECTION_CLASSES: dict[str, type]

def enclosure_shape(geometry: GeometrySection) -> Enclosure | None: ...
def plain_section(section: Any) -> dict[str, Any]: ...
def typed_section(section: str, values: dict[str, Any]) -> Any: ...
def stub_text() -> str: ...
