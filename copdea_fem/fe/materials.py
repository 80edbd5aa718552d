"""Electro-hyperelastic constitutive law of the DE membrane: eqs (7) and (20).

Everything here is a pure function of the in-plane invariants of the right
Cauchy-Green tensor measured from the *unstretched* film,

    tr_c  = lambda_1**2 + lambda_2**2          (trace of the 2x2 tangent C),
    det_c = lambda_1**2 * lambda_2**2          (its determinant),

so that the same code evaluates NumPy arrays (ring model, hand checks) and
NGSolve CoefficientFunctions (FE energy, differentiated symbolically by
NGSolve).  Plane-stress incompressibility (eq. 1) gives the thickness stretch
``lambda_3**2 = 1 / det_c``.

Energies are densities per unit *unstretched* volume [J/m^3]; stresses are
true (Cauchy) stresses [Pa]; tensions are forces per deformed length [N/m].
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

VACUUM_PERMITTIVITY = 8.8541878128e-12  # F/m (CODATA 2018)


@dataclass(frozen=True)
class Membrane:
    """Material and film data of the DE membrane (Table 1 of the paper).

    Attributes
    ----------
    c10, c20, c01 : float
        Generalised Mooney-Rivlin coefficients of eq. (20) [Pa].
    permittivity : float
        Absolute permittivity epsilon = eps_r * eps_0 [F/m].
    thickness : float
        Film thickness h0 before pre-stretch [m].
    density : float
        Mass density rho0 [kg/m^3] (referred to h0, electrodes included).
    prestretch : float
        Pre-stretch lambda_p [-] (equibiaxial when ``anisotropy`` is 0).
    anisotropy : float
        Anisotropy e of the pre-stretch [-]: the film is pre-stretched by lambda_p (1 + e)
        along ``anisotropy_axis`` and lambda_p (1 - e) across it (study key
        ``membrane.prestretch_anisotropy``; :mod:`copdea_fem.fe.membrane`).
    anisotropy_axis : float
        Direction of the larger pre-stretch [rad], counter-clockwise from x.
    thickness_variation : tuple
        ``((k, a, angle [rad]), ...)``: the film's thickness before pre-stretch is
        h0 (1 + sum a cos k (theta - angle)) (``membrane.thickness_variation``).
    """

    c10: float
    c20: float
    c01: float
    permittivity: float
    thickness: float
    density: float
    prestretch: float
    anisotropy: float = 0.0
    anisotropy_axis: float = 0.0
    thickness_variation: tuple = ()

    @classmethod
    def from_study(cls, study) -> "Membrane":
        m = study.membrane
        return cls(c10=m.c10, c20=m.c20, c01=m.c01,
                   permittivity=m.relative_permittivity * VACUUM_PERMITTIVITY,
                   thickness=m.thickness, density=m.density,
                   prestretch=m.prestretch, anisotropy=m.prestretch_anisotropy,
                   anisotropy_axis=float(np.radians(m.prestretch_axis)),
                   thickness_variation=tuple((term.order, term.amplitude,
                                              float(np.radians(term.angle)))
                                             for term in m.thickness_variation))

    @property
    def uniform(self) -> bool:
        """Whether the film is equibiaxially pre-stretched and of even thickness (the
        perfect device)."""
        return self.anisotropy == 0 and not self.thickness_variation

    @property
    def area_stretch(self) -> float:
        """det F_p = lambda_p^2 (1 - e^2) [-]: pre-stretched over unstretched area (and
        h0 over the pre-stretched thickness, incompressibility)."""
        return self.prestretch**2 * (1 - self.anisotropy**2)

    @classmethod
    def with_effects(cls, study) -> "Membrane":
        """The FE's membrane: :meth:`from_study` with the diagnosis keys of section
        ``effects`` applied -- c10, c20, c01 times ``stiffness_scale``, the permittivity
        times ``maxwell_scale`` (an effective permittivity: the whole electrostatic term of
        eq. (7) scales, as V_eff = sqrt(maxwell_scale) V_b does in the ring model's
        equilibrium and K_s; in the FE the forcing scales with it)."""
        nominal = cls.from_study(study)
        effects = study.effects
        stiffness, maxwell = effects.stiffness_scale, effects.maxwell_scale
        if stiffness == 1.0 and maxwell == 1.0:
            return nominal
        return replace(nominal, c10=stiffness * nominal.c10, c20=stiffness * nominal.c20,
                       c01=stiffness * nominal.c01, permittivity=maxwell * nominal.permittivity)

    @property
    def prestretched_thickness(self) -> float:
        """h0 / lambda_p**2 [m] (incompressibility, Sect. 2); h0 / (lambda_p^2 (1 - e^2))
        with an anisotropic pre-stretch (the mean over theta with a thickness variation)."""
        if self.anisotropy == 0:
            return self.thickness / self.prestretch**2
        return self.thickness / self.area_stretch

    @property
    def areal_density(self) -> float:
        """Mass per flat pre-stretched area rho0 h0 / lambda_p**2 [kg/m^2]."""
        return self.density * self.prestretched_thickness

    def nominal_field_sq(self, voltage):
        """(V / h0)**2 [V^2/m^2], the nominal field of eq. (7) squared."""
        return (voltage / self.thickness) ** 2

    # -- eq. (20) + (7) ---------------------------------------------------------
    def strain_energy(self, tr_c, det_c):
        """Generalised Mooney-Rivlin energy Psi_m of eq. (20) [J/m^3].

        I1 = l1^2 + l2^2 + l3^2 = tr_c + 1/det_c and
        I_{-1} = l1^-2 + l2^-2 + l3^-2 = tr_c/det_c + det_c (2x2 Cayley-Hamilton).
        """
        i1 = tr_c + 1 / det_c
        i_inv = tr_c / det_c + det_c
        return self.c10 * (i1 - 3) + self.c20 * (i1 - 3) ** 2 + self.c01 * (i_inv - 3)

    def electrostatic_coenergy(self, det_c, voltage):
        """Co-energy -eps/2 (V/h0)^2 J/C33 of eq. (7) [J/m^3]; J = 1, C33 = 1/det_c."""
        return -0.5 * self.permittivity * self.nominal_field_sq(voltage) * det_c

    def free_energy(self, tr_c, det_c, voltage):
        """Psi_em of eq. (7): elastic energy plus electrostatic co-energy [J/m^3]."""
        return self.strain_energy(tr_c, det_c) + self.electrostatic_coenergy(det_c, voltage)

    def free_energy_partials(self, tr_c, det_c, voltage):
        """First and second partial derivatives of Psi_em in (tr_c, det_c).

        Returns
        -------
        d_tr, d_det, d_tr_tr, d_tr_det, d_det_det
            Exact derivatives [J/m^3] (derived by hand from eq. 20 and 7; the
            tests check them against finite differences).
        """
        i1m3 = tr_c + 1 / det_c - 3
        g = self.c10 + 2 * self.c20 * i1m3          # dPsi/dI1
        d_tr = g + self.c01 / det_c
        d_det = (-g / det_c**2 + self.c01 * (1 - tr_c / det_c**2)
                 - 0.5 * self.permittivity * self.nominal_field_sq(voltage))
        d_tr_tr = 2 * self.c20 + 0 * tr_c
        d_tr_det = -2 * self.c20 / det_c**2 - self.c01 / det_c**2
        d_det_det = (2 * self.c20 / det_c**4 + 2 * g / det_c**3
                     + 2 * self.c01 * tr_c / det_c**3)
        return d_tr, d_det, d_tr_tr, d_tr_det, d_det_det

    # -- stresses and fields ----------------------------------------------------
    def principal_stresses(self, stretch_1, stretch_2, voltage):
        """In-plane principal Cauchy stresses [Pa] at principal stretches l1, l2.

        sigma_i = l_i dPsi/dl_i with l3 = 1/(l1 l2) eliminated (plane stress,
        incompressible).  With tr = l1^2 + l2^2, det = l1^2 l2^2:
        sigma_1 = 2 l1^2 (Psi_tr + l2^2 Psi_det).  The electrostatic part is the
        Maxwell stress -eps (V/h)^2 with h = h0 l3.
        """
        s1 = np.asarray(stretch_1, dtype=float)
        s2 = np.asarray(stretch_2, dtype=float)
        tr_c, det_c = s1**2 + s2**2, s1**2 * s2**2
        d_tr, d_det, *_ = self.free_energy_partials(tr_c, det_c, voltage)
        return 2 * s1**2 * (d_tr + s2**2 * d_det), 2 * s2**2 * (d_tr + s1**2 * d_det)

    def thickness_at(self, det_c):
        """Deformed thickness h = h0 lambda_3 = h0 / sqrt(det_c) [m]."""
        return self.thickness / det_c**0.5

    def electric_field(self, det_c, voltage):
        """True electric field V / h [V/m] across the deformed film."""
        return voltage * det_c**0.5 / self.thickness

    def equibiaxial_tension(self, voltage, stretch=None) -> float:
        """Membrane tension T = h sigma [N/m] of the flat film at stretch lambda_p.

        This is the tension of the closed forms (Bessel roots, 2 pi T / ln(ro/ri)).
        """
        lam = self.prestretch if stretch is None else stretch
        sigma, _ = self.principal_stresses(lam, lam, voltage)
        return float(sigma) * self.thickness / lam**2
