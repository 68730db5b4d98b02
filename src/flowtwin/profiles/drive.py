"""Extruder drive profile: which roller, how hard it pinches, how far it turns.

A drive refers to one of the seven rollers of [000] by ``roller_id`` or defines its own
``[custom_roller]`` table (same keys as a row of ``rollers.toml``). ``[slip_overrides]``
replaces single slip parameters of the chosen roller (paper units, like the table); giving
``b`` or ``c`` makes the roller velocity dependent (then ``a``, ``b`` and ``c`` must all be
known). :meth:`DriveProfile.resolve_roller` returns the roller with the overrides applied.
"""

from __future__ import annotations

from collections.abc import Mapping

from pydantic import Field, model_validator

from flowtwin.errors import ProfileError
from flowtwin.profiles.base import NamedProfile, ProfileModel
from flowtwin.profiles.rollers import Roller
from flowtwin.profiles.validation import validate_model

__all__ = ["DriveProfile", "SlipOverrides"]


class SlipOverrides(ProfileModel):
    """Replacement values for slip parameters of the roller (paper units, [000 Table 3])."""

    k_s_pct_N: float | None = Field(None, gt=0.0, le=1e5, description="k_s, %·N.")
    k_inf_pct_per_N: float | None = Field(None, gt=0.0, le=100.0, description="k_∞, %/N.")
    a_pct_per_N: float | None = Field(None, gt=0.0, le=100.0, description="a of Eq. 8, %/N.")
    b_pct_per_N: float | None = Field(None, gt=0.0, le=100.0, description="b of Eq. 8, %/N.")
    c_s_per_mm: float | None = Field(None, gt=0.0, le=100.0, description="c of Eq. 8, s/mm.")

    def given(self) -> dict[str, float]:
        """The overrides that are set, by field name."""
        return {k: v for k, v in self.model_dump().items() if v is not None}


class DriveProfile(NamedProfile):
    """Filament drive (cold end) [000].

    ``rotation_distance_mm`` is the filament advanced per turn of the roller without slip,
    ``2π·r`` in the notation ``v_nom = ω·r`` of [000 Eq. 1] (Klipper's
    ``rotation_distance``); ``gear_ratio`` is motor turns per roller turn.
    ``k_p_pct`` is the set-up specific slip offset of [000 Eq. 6], found by calibration.
    """

    roller_id: int | None = Field(None, ge=1, le=7,
                                  description="Roller number of [000] Tables 2–3.")
    custom_roller: Roller | None = Field(None, description="A roller not in [000] (give "
                                                           "instead of roller_id).")
    pinch_force_n: float = Field(gt=0.0, le=500.0,
                                 description="Pinch force F_p between roller and idler, N.")
    rotation_distance_mm: float = Field(gt=0.0, le=1000.0,
                                        description="Filament per roller turn, mm.")
    gear_ratio: float = Field(1.0, gt=0.0, le=100.0,
                              description="Motor turns per roller turn.")
    k_p_pct: float = Field(0.0, ge=-100.0, le=100.0,
                           description="Slip offset k_p of Eq. 6, %.")
    slip_overrides: SlipOverrides | None = Field(None, description="Replace single slip "
                                                                   "parameters of the roller.")

    @model_validator(mode="after")
    def _one_roller(self) -> DriveProfile:
        if (self.roller_id is None) == (self.custom_roller is None):
            raise ValueError("give exactly one of roller_id (1-7, a roller of [000]) or a "
                             "[custom_roller] table")
        return self

    @property
    def k_p(self) -> float:
        """Slip offset k_p as a fraction (``k_p_pct / 100``)."""
        return self.k_p_pct / 100.0

    def resolve_roller(self, rollers: Mapping[int, Roller]) -> Roller:
        """Return the roller this drive uses, with :attr:`slip_overrides` applied.

        Parameters
        ----------
        rollers
            The catalogue, e.g. :func:`flowtwin.profiles.load_rollers`.

        Returns
        -------
        Roller
            The catalogue or custom roller. If an override changes ``k_s`` or ``k_∞`` the
            tabulated ``F_p,min`` no longer belongs to the parameters and is dropped.

        Raises
        ------
        ProfileError
            If ``roller_id`` is not in ``rollers`` or the overrides make an invalid roller.
        """
        if self.custom_roller is not None:
            roller = self.custom_roller
        else:
            assert self.roller_id is not None  # guaranteed by the validator
            if self.roller_id not in rollers:
                raise ProfileError(f"drive {self.name!r} refers to an unknown roller",
                                   field="roller_id", value=self.roller_id,
                                   allowed=", ".join(str(k) for k in sorted(rollers)))
            roller = rollers[self.roller_id]
        if self.slip_overrides is None:
            return roller
        update: dict[str, object] = dict(self.slip_overrides.given())
        if not update:
            return roller
        if "b_pct_per_N" in update or "c_s_per_mm" in update:
            update["velocity_dependent"] = True
        if "k_s_pct_N" in update or "k_inf_pct_per_N" in update:
            update.update(fp_min_tabulated_N=None, fp_min_note=None, k_s_pct_N_err=None,
                          k_inf_pct_per_N_err=None)
        data = roller.model_dump()
        data.update(update)
        data["source"] = (roller.source + f"; slip parameters overridden by drive "
                          f"{self.name!r}").lstrip("; ")[:2000]
        # Re-validate so overrides cannot make an inconsistent roller (e.g. b without c).
        return validate_model(Roller, data, source=f"drive {self.name!r} [slip_overrides]")
