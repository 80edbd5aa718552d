"""What an effect of the catalogue is (:mod:`copdea_fem.diagnosis.effects`): the record
:class:`Effect` and its parts -- a fitted :class:`Parameter` (SI unit, fit bounds, physical
default), a :class:`Requirement` the base study or the data must meet for it to be tested
(:data:`HAS_DISC`, :data:`BIASED`, :data:`RAISED`), an :class:`Exclusion` of effects never
in the model beside it.  No effect is named here: the catalogue holds them all.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from copdea_fem.study import StudyError

@dataclass(frozen=True)
class Parameter:
    """One fitted parameter of an effect.

    Attributes
    ----------
    name : str
        Short identifier (``"scale"``, ``"mass"``).
    key : str
        Study key it sets (``"effects.air_mass_scale"``).
    unit : str or None
        SI unit of the value (None: a pure number).
    default : float
        Physical default, the start of every fit [unit].
    lower, upper : float
        Fit bounds [unit].
    log : bool
        Fit in log space (positive scale factors, masses, times).
    description : str
    surrogate_only : bool
        Only the ring surrogate reads it, although the FE represents the effect
        (air_loading's scale: the FE has the real coupled air).  The direct FE engine
        holds it at its default (not fitted), and an FE anchor takes the default.
    """

    name: str
    key: str
    unit: str | None
    default: float
    lower: float
    upper: float
    log: bool
    description: str
    surrogate_only: bool = False

    def __post_init__(self):
        if not self.lower <= self.default <= self.upper or (self.log and self.lower <= 0):
            raise ValueError(f"parameter {self.name}: default {self.default!r} is not allowed; "
                             f"allowed: [{self.lower!r}, {self.upper!r}] (> 0 when log)")

    def shown(self, value: float) -> str:
        """``value`` with its unit, in the unit a reader expects (g, ms)."""
        if self.unit == "kg":
            return f"{value * 1e3:.4g} g"
        if self.unit == "s":
            return f"{value * 1e3:.4g} ms"
        return f"{value:.4g}" + (f" {self.unit}" if self.unit else "")


@dataclass(frozen=True)
class Requirement:
    """A condition an effect needs in the base study or the data to be tested.

    Attributes
    ----------
    holds : callable
        ``(study, conditions) -> bool``: ``study`` the base study, ``conditions`` the
        operating points of the measured conditions, mappings with ``voltage`` [V] and
        ``z`` [m].
    reason : str
        Why the effect is not tested where it does not hold (the report prints it).
    """

    holds: Callable = field(repr=False)
    reason: str = ""


HAS_DISC = Requirement(lambda study, conditions: study.geometry.inner_radius != 0,
                       "a membrane without a disc has no disc to pump")
BIASED = Requirement(lambda study, conditions: any(c["voltage"] > 0 for c in conditions),
                     "every condition has V_b = 0: nothing to soften")
RAISED = Requirement(lambda study, conditions: any(c["z"] > 0 for c in conditions),
                     "every condition has z = 0: the pumping modes are not driven")


@dataclass(frozen=True)
class Exclusion:
    """Effects never in the model beside the effect that declares the exclusion.

    Attributes
    ----------
    effects : tuple of str
        The effects it excludes, in the order a reason names them.
    rule : str
        The rule as the report states it (``"one material-damping cause at a time"``).
    why : str
        Why the declaring effect is not tested beside one of ``effects``.
    what : str
        What the declaring effect is, said where it keeps one of ``effects`` out.
    """

    effects: tuple
    rule: str
    why: str
    what: str


@dataclass(frozen=True)
class SplitTrial:
    """One FE solve that measures how an imperfection splits the (m,n) pairs
    (:mod:`copdea_fem.diagnosis.imperfections`): the imperfection at a trial size along the
    angle 0 (both mirror planes through x kept, so the members are the cos / sin ones).

    Attributes
    ----------
    name : str
        What the trial is (``"order 2"``, ``"r = 24 mm"``), for the report.
    overrides : dict
        Study overrides of the imperfection at ``amplitude`` and angle 0.
    amplitude : float
        The trial size of the fitted magnitude [its parameter's unit].
    power : callable
        ``power(m) -> float or None``: the order in the magnitude at which the pair of
        order m splits (perturbation theory: a cos k theta term couples orders m and
        m +- k, so the members of an m pair, 2m apart, split at order j = 2m / k where
        that is an integer; a point mass couples every order: 1); None: no split.
    angle_period : float
        The period [deg] of the imperfection's angle (180 for an axis, 360 / k for an
        order-k term, 360 for a mass).
    fixed : tuple
        Values [parameter units] of the parameters the trial fixes, in the effect's
        parameter order, None where fitted (a mass's radius, a term's order).
    """

    name: str
    overrides: dict
    amplitude: float
    power: Callable = field(repr=False)
    angle_period: float
    fixed: tuple = ()


@dataclass(frozen=True)
class SplitSignature:
    """How an imperfection is named from split pairs: its trial FE solves and how its
    parameters are read back (:mod:`copdea_fem.diagnosis.imperfections`).

    Attributes
    ----------
    trials : callable
        ``trials(study) -> tuple of SplitTrial`` for the base study at a condition.
    values : callable
        ``values(trial, magnitude, angle_deg) -> tuple``: the effect's parameter values
        (its :attr:`Effect.parameters` order) of a fit; ``angle_deg`` NaN where no
        orientation was measured.
    continuous : bool
        Consecutive trials lie on a continuous parameter (a mass's radius): the splits
        between them are interpolated; False: the trials are discrete choices (an order).
    magnitude : int
        Index in :attr:`Effect.parameters` of the parameter the fitted magnitude sets (the
        trial's ``amplitude`` scaled): its bounds bound the fit (a thickness amplitude
        below 0.9, an anisotropy below 0.3), so no fit leaves the range its study key
        allows.
    in_air : bool
        The trials keep the air where the measured conditions have it (``air.enabled``);
        False: in vacuo, where the air loads both members of a pair alike (an anisotropy:
        the relative split is unchanged; a mass: smaller in air, the fitted mass a lower
        bound).  True where the imperfection changes both the film's stiffness and its
        mass (a thickness term): in vacuo they cancel in the split, the air's added mass
        does not scale with the film.
    moves_with_bias : bool
        Its splits move with the bias voltage (a thickness term: the strain energy scales
        with t, the electrostatic co-energy with 1/t, so its split follows the
        electrostatic stress ~ V^2); False: hardly (an anisotropy's is the pre-stretch's).
        Two such imperfections that explain one bias's splits alike are told apart by a
        condition at another bias.
    """

    trials: Callable = field(repr=False)
    values: Callable = field(repr=False)
    continuous: bool = False
    magnitude: int = 0
    in_air: bool = False
    moves_with_bias: bool = False


FE_ROLES_ALLOWED = (None, "switch", "anchored")
MOUNTING_KINDS = (None, "built", "open")


@dataclass(frozen=True)
class Effect:
    """One physical effect: what it is, its parameters, its signature, how to apply it.

    Attributes
    ----------
    id : str
        Stable snake_case identifier (a contract).
    title : str
    description : str
        What the effect is physically, with the paper's section.
    kind : str
        ``"physics"`` or ``"parameter"``.
    engine : str
        ``"reduced"``, ``"coupled_fe"`` or ``"fe"`` (module notes).
    parameters : tuple of Parameter
    signature : str
        The residual pattern it explains (what a reader should see in the data).
    requires : tuple of str
        Effects that must be on for this one to act (spring_mass needs disc_pumping).
    needs : str
        What the data must contain to test it: ``"frequencies"`` or
        ``"quality_factors"`` (peak widths from resonances or spectra).
    on_overrides, off_overrides, detect : callables
        ``(study, values) -> overrides``, ``(study) -> overrides``, ``(study) -> bool``.
    fe_role : str or None
        How the FE model of record represents it (:mod:`copdea_fem.diagnosis.anchored`):
        ``"switch"`` (the ring model cannot: on in the FE whenever on in the state),
        ``"anchored"`` (the ring model moves it well: in the FE from the step that
        accepts it, at the accepted values) or None (the ring model alone).
    direct : bool
        The FE evaluates it by itself (its study keys: geometry, air,
        ``diagnosis.fe.FE_EFFECT_KEYS``), so the direct FE engine can test it.
    not_direct : str
        Why the direct FE engine does not test it, where the general reason (it needs
        the ring surrogate and the FE does not model it) is not the one.
    visible_in_scan : bool
        The FE honours it, so a synthetic vibrometer export (made by the FE) can hide it.
    mounting : str or None
        A mounting (one at a time; each replaces the base's own): ``"built"`` (a part
        built around or behind the membrane, kept by a base that states it without air)
        or ``"open"`` (nothing around the membrane); None: not a mounting.
    replaces : tuple of str
        Effects its overrides switch off where the base has them on (besides the other
        mountings, which a mounting always replaces).
    exclusion : Exclusion or None
        Effects never tested beside this one, nor this one beside them.
    applies_when : tuple of Requirement
        What the base study and the data must offer for it to be tested
        (:meth:`applies_to`).
    adds_air : bool
        It puts the air in the model: the coupled-FE effects are tested once it is on,
        and it is what a measurement in vacuo lacks.
    changes_prestress : bool
        Its parameters change the static (prestressed) state: the ring surrogate solves
        it again at every value, so its tabulation is coarser.
    prony_term : bool
        Its values are one Prony term ``(g, tau [s])`` of ``membrane.prony``, which the FE
        anchor moves by a modal surrogate.
    switched_keys : tuple of str
        Study keys (or key prefixes) it switches, which a condition of
        ``measured.yaml`` may therefore not set.
    opt_in : bool
        Tested only where ``measured.yaml``'s ``candidates`` name it.
    not_tested_note : str
        A line the report adds when it was not tested.
    split_signature : SplitSignature or None
        An imperfection of a round device, named from split (m,n) pairs and their
        orientations (:mod:`copdea_fem.diagnosis.imperfections`), never a candidate of the
        search over the round model (:mod:`copdea_fem.diagnosis.select`), which cannot
        split a pair.
    """

    id: str
    title: str
    description: str
    kind: str
    engine: str
    parameters: tuple
    signature: str
    on_overrides: Callable = field(repr=False)
    off_overrides: Callable = field(repr=False)
    detect: Callable = field(repr=False)
    requires: tuple = ()
    needs: str = "frequencies"
    fe_role: str | None = None
    direct: bool = False
    not_direct: str = ""
    visible_in_scan: bool = False
    mounting: str | None = None
    replaces: tuple = ()
    exclusion: Exclusion | None = None
    applies_when: tuple = ()
    adds_air: bool = False
    changes_prestress: bool = False
    prony_term: bool = False
    switched_keys: tuple = ()
    opt_in: bool = False
    not_tested_note: str = ""
    split_signature: SplitSignature | None = None

    def __post_init__(self):
        for name, value, allowed in (("fe_role", self.fe_role, FE_ROLES_ALLOWED),
                                     ("mounting", self.mounting, MOUNTING_KINDS)):
            if value not in allowed:
                raise ValueError(f"effect {self.id}: {name} = {value!r} is not allowed; "
                                 f"allowed: {', '.join(map(str, allowed))}")

    @property
    def defaults(self) -> tuple:
        return tuple(p.default for p in self.parameters)

    def on(self, study, values=None) -> dict:
        """Overrides that switch the effect on with ``values`` (default: the physical defaults)."""
        values = self.defaults if values is None else tuple(float(v) for v in values)
        if len(values) != len(self.parameters):
            raise StudyError(f"{self.id} parameters = {values!r} is not allowed; allowed: "
                             f"{len(self.parameters)} values ({self.parameter_names or 'none'})")
        return self.on_overrides(study, values)

    def off(self, study) -> dict:
        """Overrides that switch the effect off."""
        return self.off_overrides(study)

    def is_on(self, study) -> bool:
        return bool(self.detect(study))

    @property
    def parameter_names(self) -> str:
        return ", ".join(p.name for p in self.parameters)

    def describe_values(self, values) -> str:
        return ", ".join(f"{p.name} = {p.shown(v)}" for p, v in zip(self.parameters, values))

    def anchor_values(self, values) -> tuple:
        """``values`` as an FE anchor takes them: the surrogate-only parameters at
        their defaults (:attr:`Parameter.surrogate_only`)."""
        return tuple(p.default if p.surrogate_only else v
                     for p, v in zip(self.parameters, values))

    def why_not_applicable(self, study, conditions) -> str | None:
        """The reason of the first requirement (:attr:`applies_when`) that ``study`` (the
        base study) and ``conditions`` (mappings with ``voltage`` [V] and ``z`` [m], one
        per measured condition) do not meet; None: it applies."""
        return next((r.reason for r in self.applies_when if not r.holds(study, conditions)),
                    None)

    def applies_to(self, study, conditions) -> bool:
        """Whether the effect can be tested on the base ``study`` with these ``conditions``
        (:meth:`why_not_applicable`)."""
        return self.why_not_applicable(study, conditions) is None

    @property
    def acts_through_air(self) -> bool:
        """The air loading or a mounting: an effect that acts through the air only."""
        return self.adds_air or self.mounting is not None

    def replaces_effect(self, other: "Effect") -> bool:
        """Whether switching this effect on replaces ``other`` where the base has it on:
        a mounting replaces every other mounting, and any effect those in :attr:`replaces`."""
        return other.id in self.replaces or (self.mounting is not None
                                             and other.mounting is not None
                                             and other.id != self.id)
