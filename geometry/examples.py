"""Constructors of textbook designs (generic coaxial stacks) used by tests and users.

All return a validated :class:`~geometry.design_stack.StackDesign`; ``examples.toml`` beside this
module holds the same designs with default arguments (``python -m geometry --design
geometry/examples.toml --select k31_bar``).
"""

from __future__ import annotations

from dataclasses import replace

from .design_rpud import RPUDDesign, default_design
from .design_stack import ElectrodeSpec, Segment, StackDesign

__all__ = ["k33_rod", "k31_bar", "langevin_sandwich", "slender_rod", "bonded_sandwich", "bolted_design", "article_design", "EXAMPLES",
           "all_examples"]


def k33_rod(material: str = "PZT-4", length: float = 0.04, diameter: float = 0.004,
            target_frequency: float = 40e3) -> StackDesign:
    """A piezoceramic rod poled along its length, electrodes on both ends (IEEE 176 k33).

    Parameters
    ----------
    material : str
    length, diameter : float
        m (slender by default: L/R = 20, see the Rayleigh-Love pitfall).
    target_frequency : float
        Hz, for the mesh size rule.
    """
    return StackDesign(
        name="k33_rod", target_frequency=target_frequency,
        segments=(Segment("rod", length, kind="cylinder", material=material, outer_diameter=diameter, poling="+z"),),
        electrodes=(ElectrodeSpec("electrode_bottom", "rod", "bottom", "ground"),
                    ElectrodeSpec("electrode_top", "rod", "top", "hot")))


def k31_bar(material: str = "PZT-4", length: float = 0.04, width: float = 0.004, thickness: float = 0.001,
            target_frequency: float = 40e3) -> StackDesign:
    """A rectangular bar (length along z, ``thickness`` along x, ``width`` along y) poled
    through the thickness (+x), electrodes on the two large faces x = +-thickness/2 (IEEE 176 k31)."""
    return StackDesign(
        name="k31_bar", target_frequency=target_frequency,
        segments=(Segment("bar", length, kind="box", material=material, thickness=thickness, width=width, poling="+x"),),
        electrodes=(ElectrodeSpec("electrode_minus_x", "bar", "-x", "ground"),
                    ElectrodeSpec("electrode_plus_x", "bar", "+x", "hot")))


def langevin_sandwich(metal: str = "steel_45", ceramic: str = "PZT-8", metal_length: float = 0.04,
                      ceramic_length: float = 0.01, diameter: float = 0.03,
                      target_frequency: float = 25e3) -> StackDesign:
    """A metal / ceramic / metal sandwich: two metal cylinders with two rings poled -z and +z
    between them; the middle electrode is hot, the two outer ones ground (touching metal)."""
    return StackDesign(
        name="langevin", target_frequency=target_frequency,
        segments=(Segment("back", metal_length, material=metal, outer_diameter=diameter),
                  Segment("ring_1", ceramic_length / 2, material=ceramic, outer_diameter=diameter, poling="-z", part="stack"),
                  Segment("ring_2", ceramic_length / 2, material=ceramic, outer_diameter=diameter, poling="+z", part="stack"),
                  Segment("front", metal_length, material=metal, outer_diameter=diameter)),
        electrodes=(ElectrodeSpec("electrode_0", "ring_1", "bottom", "ground"),
                    ElectrodeSpec("electrode_1", "ring_1", "top", "hot"),
                    ElectrodeSpec("electrode_2", "ring_2", "top", "ground")))


def slender_rod(material: str = "steel_45", length: float = 0.2, diameter: float = 0.01,
                target_frequency: float = 13e3) -> StackDesign:
    """A slender passive rod (free-free longitudinal and torsional checks)."""
    return StackDesign(name="slender_rod", target_frequency=target_frequency,
                       segments=(Segment("rod", length, material=material, outer_diameter=diameter),))


def bonded_sandwich(metal: str = "al7075", ceramic: str = "PZT-4", bond: str = "epoxy",
                    diameter: float = 0.055, metal_thickness: float = 0.0125, ceramic_thickness: float = 0.005,
                    bond_thickness: float = 0.000275, target_frequency: float = 40e3) -> StackDesign:
    """A bonded disc sandwich: metal disc / bond / piezoceramic disc / bond / metal disc.

    The ceramic is poled +z with its electrodes on its two faces (bottom ground, top hot),
    where it meets the bond layers. The bonds are far thinner than the element size and are
    meshed as structured layers (:mod:`geometry.layers`). With the defaults (55 mm discs of
    aluminium 12.5 mm, PZT-4 5 mm, two 0.275 mm epoxy bonds) the first thickness-mode
    resonance, the symmetric mode in which the two metal discs move apart and strain the
    ceramic through the bonds, lies near 47 kHz.

    Parameters
    ----------
    metal, ceramic, bond : str
        Library material names.
    diameter : float
        Of every disc, m.
    metal_thickness, ceramic_thickness, bond_thickness : float
        m (each metal disc; the ceramic; each bond).
    target_frequency : float
        Hz, for the mesh size rule.
    """
    return StackDesign(
        name="bonded_sandwich", target_frequency=target_frequency,
        segments=(Segment("back", metal_thickness, material=metal, outer_diameter=diameter),
                  Segment("bond_1", bond_thickness, material=bond, outer_diameter=diameter),
                  Segment("disc", ceramic_thickness, material=ceramic, outer_diameter=diameter, poling="+z"),
                  Segment("bond_2", bond_thickness, material=bond, outer_diameter=diameter),
                  Segment("front", metal_thickness, material=metal, outer_diameter=diameter)),
        electrodes=(ElectrodeSpec("electrode_bottom", "disc", "bottom", "ground"),
                    ElectrodeSpec("electrode_top", "disc", "top", "hot")))


def bolted_design(horn_length: float = 0.07549045, coupler_length: float = 0.05355691,
                  step_fraction: float = 0.57, slot_offset: float = 0.008,
                  horn_back_diameter: float = 0.030, bolt_joint: str = "faces") -> RPUDDesign:
    """The drill with its M12 bolt part (``stack.bolt_diameter`` 12 mm) bonded at the stack's
    faces, designed with the bolt: the default drill (:func:`~geometry.design_rpud.default_design`)
    with the faces' joint and its lengths matched with that joint.

    The bolt stiffens the working mode, so the match lengthens the horn and the coupler, and
    the drill's torsional modes fall (the bolt adds almost no torsional stiffness). Two changes
    restore the rotary drive. At the article's step (``step_fraction`` 0.5) the horn's thin tip
    section is a torsional quarter wave at the drive (``c_T / (4 L_tip)`` = 19.8 kHz), a dynamic
    absorber that stills the teeth's torsion; a step at 0.57 of the horn puts it near 24 kHz.
    The torsional mode that drives the teeth then lies below the drive (19.1 kHz with the
    article's 24 mm horn back, teeth phase 7 deg: a slow rotor); the horn's back section's polar
    moment (``d^4``) lifts it, and a 30 mm back puts it at 20.9 kHz, just above the drive as in
    the article's drill (phase 173 deg). The slot zone 8 mm from the teeth roots (4 mm in the
    article's drill) takes the twist where the coupler's axial strain is larger
    (benchmarks/study_bolted_coupler.py). The lengths are the ones matched to 20 kHz on the
    k = 0 sector at refine 1 (the pipeline's matching).

    Parameters
    ----------
    horn_length, coupler_length : float
        Matched lengths, m.
    step_fraction : float
        The horn's back-section share of its length, dimensionless.
    slot_offset : float
        Gap between the teeth roots and the slotted zone, m.
    horn_back_diameter : float
        Diameter of the horn's back section, m.
    bolt_joint : {"faces", "thread"}
        How the bolt meets the metal (:attr:`geometry.design_rpud.StackRings.bolt_joint`): the
        lengths are matched with ``"faces"``; ``"thread"`` keeps them (the thread's effect at
        fixed lengths, docs/theory/operating-point.md).
    """
    d = RPUDDesign()
    horn = replace(d.horn, length=horn_length, step_fraction=step_fraction, back_diameter=horn_back_diameter)
    return RPUDDesign(name="bolted", horn=horn, stack=replace(d.stack, bolt_diameter=0.012, bolt_joint=bolt_joint), flange=d.flange,
                      coupler=replace(d.coupler, length=coupler_length, slot_offset=slot_offset))


def article_design() -> RPUDDesign:
    """The article's drill as drawn in its Table 1: no bolt part (the bolt is its prestress on
    the rings only), the 24 mm horn back stepped at half its length, slots 4 mm from the teeth,
    and the horn and coupler lengths (68.04 mm, 49.701 mm) matched to 20 kHz on the k = 0
    sector at refine 1 (the pipeline's match returns them within its tolerance).

    These are the field defaults of :class:`~geometry.design_rpud.RPUDDesign`. The default
    drill (:func:`~geometry.design_rpud.default_design`) departs from it to carry its elastic
    threaded bolt; compare the two with ``--design article``. Without the bolt part its f_r
    sits about 10 % below a bolted build of the same lengths, which the report states as a
    model-form error (:data:`fem.preload.ELASTIC_BOLT_FR_SHIFT`).
    """
    return RPUDDesign(name="article")


EXAMPLES = {"k33_rod": k33_rod, "k31_bar": k31_bar, "langevin": langevin_sandwich,
            "slender_rod": slender_rod, "bonded_sandwich": bonded_sandwich, "rpud": default_design,
            "article": article_design, "bolted": bolted_design}
"""Name -> constructor with default arguments."""


def all_examples() -> dict[str, StackDesign | RPUDDesign]:
    """Every example design with its default arguments."""
    return {name: make() for name, make in EXAMPLES.items()}
