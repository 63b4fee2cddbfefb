"""Contact mechanics: the stiffness of a contact between two elastic bodies.

A contact that presses with a normal force F is a spring as well as a damper.  Its normal
stiffness follows from Hertz's theory of two elastic spheres (or a sphere on a flat) of
effective radius R, and a sticking (not sliding) contact also resists a tangential
displacement with Mindlin's no-slip stiffness.  Both grow with the contact radius a, which
grows as F^(1/3): a firmer press is a stiffer spring.

Formulas (K. L. Johnson, *Contact Mechanics*, Cambridge University Press 1985: eq. 4.22-4.23
for Hertz, section 7.2 for Mindlin; R. D. Mindlin, "Compliance of elastic bodies in contact",
J. Appl. Mech. 16 (1949) 259-268):

    1 / E* = (1 - nu1^2) / E1 + (1 - nu2^2) / E2         effective modulus
    1 / G* = (2 - nu1) / G1 + (2 - nu2) / G2              (G = E / (2 (1 + nu)))
    a      = (3 F R / (4 E*))^(1/3)                       Hertz contact radius
    k_n    = dF/d(delta) = 2 E* a                         normal stiffness
    k_t    = 8 G* a                                       tangential (Mindlin, no slip)

For two bodies of one material k_t / k_n = 2 (1 - nu) / (2 - nu) (0.82 at nu = 0.3).

The effective radius R (1 / R = 1 / R1 + 1 / R2) is rarely known for a contact that a physics
engine reports: :data:`DEFAULT_CONTACT_RADIUS_M` = 5 mm, the middle of 1-10 mm (a rounded edge
or a slightly curved face on a flat table), is the default; the stiffness changes with
R^(1/3), so a factor of 10 in R is a factor of 2.15 in k.
"""

from __future__ import annotations

import logging

from ..materials.solids import Material, get_material

log = logging.getLogger(__name__)
_WARNED: list = []

__all__ = ["DEFAULT_CONTACT_RADIUS_M", "DEFAULT_COUNTER_MATERIAL", "effective_modulus_pa",
           "effective_shear_modulus_pa", "hertz_contact_radius_m", "hertz_normal_stiffness_n_per_m",
           "mindlin_tangential_stiffness_n_per_m", "contact_stiffnesses_n_per_m"]

#: Effective radius of curvature [m] of a contact whose geometry is not known (see the module
#: docstring); a ``sensors.Contact`` field.
DEFAULT_CONTACT_RADIUS_M = 5e-3
#: The other body of a contact whose counterpart is not named: a wooden table top.
DEFAULT_COUNTER_MATERIAL = "wood"


def effective_modulus_pa(e1_pa: float, nu1: float, e2_pa: float, nu2: float) -> float:
    """Hertz's effective (plane-strain) modulus E* [Pa] of two bodies in contact."""
    return 1.0 / ((1.0 - nu1 * nu1) / e1_pa + (1.0 - nu2 * nu2) / e2_pa)


def effective_shear_modulus_pa(e1_pa: float, nu1: float, e2_pa: float, nu2: float) -> float:
    """Mindlin's effective shear modulus G* [Pa]: 1 / G* = (2 - nu1) / G1 + (2 - nu2) / G2."""
    g1, g2 = e1_pa / (2.0 * (1.0 + nu1)), e2_pa / (2.0 * (1.0 + nu2))
    return 1.0 / ((2.0 - nu1) / g1 + (2.0 - nu2) / g2)


def hertz_contact_radius_m(force_n: float, radius_m: float, effective_modulus: float) -> float:
    """Radius a [m] of the Hertz contact patch: a^3 = 3 F R / (4 E*)."""
    return (3.0 * force_n * radius_m / (4.0 * effective_modulus)) ** (1.0 / 3.0)


def hertz_normal_stiffness_n_per_m(force_n: float, radius_m: float, a: Material, b: Material) -> float:
    """Tangent normal stiffness dF/d(delta) = 2 E* a [N/m] of a Hertz contact pressed with
    ``force_n`` [N], effective radius ``radius_m`` [m], between materials ``a`` and ``b``."""
    e = effective_modulus_pa(a.youngs_modulus_pa, a.poisson_ratio, b.youngs_modulus_pa, b.poisson_ratio)
    return 2.0 * e * hertz_contact_radius_m(force_n, radius_m, e)


def mindlin_tangential_stiffness_n_per_m(force_n: float, radius_m: float, a: Material, b: Material) -> float:
    """Tangential stiffness 8 G* a [N/m] of a sticking Hertz contact (Mindlin, no slip)."""
    e = effective_modulus_pa(a.youngs_modulus_pa, a.poisson_ratio, b.youngs_modulus_pa, b.poisson_ratio)
    g = effective_shear_modulus_pa(a.youngs_modulus_pa, a.poisson_ratio, b.youngs_modulus_pa, b.poisson_ratio)
    return 8.0 * g * hertz_contact_radius_m(force_n, radius_m, e)


def contact_stiffnesses_n_per_m(contact, object_material) -> tuple[float, float]:
    """``(normal, tangential)`` stiffness [N/m] of a ``sensors.Contact`` on an object of
    ``object_material``: the contact's own values where given, else Hertz (normal) and, for a
    contact with friction (it can stick), Mindlin (tangential) from its force, ``radius_m``
    and ``counter_material``.  A contact without force does not touch: no stiffness, even a
    given one (as it has no damping).  An object material without elastic constants (a
    hand-made ``ModalBasis`` whose material holds only damping) derives none: 0, logged once."""
    if not contact.force_n > 0.0:
        return 0.0, 0.0
    kn, kt = contact.normal_stiffness_n_per_m, contact.tangential_stiffness_n_per_m
    if (kn is None or kt is None) and not isinstance(object_material, (str, Material)):
        if not _WARNED:
            _WARNED.append(True)
            log.warning("the object's material %r has no elastic constants: its contacts get no Hertz/Mindlin "
                        "springs (give Contact.normal_stiffness_n_per_m to have them)", object_material)
        return (0.0 if kn is None else float(kn)), (0.0 if kt is None else float(kt))
    if kn is None or kt is None:
        mine, other = get_material(object_material), get_material(contact.counter_material)
        if kn is None:
            kn = hertz_normal_stiffness_n_per_m(contact.force_n, contact.radius_m, mine, other)
        if kt is None:
            kt = (mindlin_tangential_stiffness_n_per_m(contact.force_n, contact.radius_m, mine, other)
                  if contact.friction > 0.0 else 0.0)
    return float(kn), float(kt)
