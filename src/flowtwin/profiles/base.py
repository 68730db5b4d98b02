"""Common base of every profile model: frozen, strict, unknown keys forbidden.

Profiles are plain validated data (docs/spec.md §5): they are read from TOML once, checked against
declared bounds, and then passed around explicitly. Every numeric field carries its unit in
its name (``_mm``, ``_mm_s``, ``_mm_s2``, ``_n``, ``_mpa``, ``_c``, ``_s``) and declares its
allowed range with ``Field(gt=..., le=...)`` so a validation error can say what is allowed.

Paper parameters keep the paper's units and are named by them (``k_s_pct_N``,
``k_inf_pct_per_N``, docs/spec.md §2); the models expose internal-unit properties next to them.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["NAME_PATTERN", "NamedProfile", "ProfileModel"]

#: Allowed profile names: letters, digits and ``. _ + -``, starting with a letter or digit.
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._+-]*$"


class ProfileModel(BaseModel):
    """Base of every profile model and sub-table.

    ``extra="forbid"``: an unknown key is an error (a typo is never silently ignored).
    ``frozen=True``: profiles are values. ``strict=True``: a string is never read as a
    number and a float never as an integer (TOML integers are accepted for float fields).
    ``allow_inf_nan=False``: ``inf``/``nan`` are rejected, so a bound check cannot be
    bypassed.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


class NamedProfile(ProfileModel):
    """A top-level profile: has a name, a one-line description and a source citation."""

    name: str = Field(min_length=1, max_length=80, pattern=NAME_PATTERN,
                      description="Profile name, used to refer to it (e.g. from a setup).")
    description: str = Field("", max_length=300, description="One-line description.")
    source: str = Field("", max_length=2000,
                        description="Where the values come from (seed citation, datasheet, "
                                    "firmware default); 'provisional' marks guesses.")
