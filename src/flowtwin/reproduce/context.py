"""Shared, cached inputs of the claims: rollers, virtual test-stand campaigns.

Several claims (and figures) use the same expensive computation — a virtual test-stand
campaign of a roller — so a :class:`ReproContext` computes each once per run and hands it
out. It is created per run and passed explicitly (no global state); its seed fixes every
random number of the run.

Campaigns (the full procedure of [000 §3], :mod:`flowtwin.teststand`):

* *pinch* — the pinch-force law [000 Eq. 6] over 10–150 N × 0.5–15 mm/s × 3 repeats, with
  the stand offset of [000 Fig. 9a] (0.63 %) and an 8 % per-record scatter of the maximum
  feed force (the "maximum fluctuations of 25 N around the global trend line" [000 §4.1]
  ≈ 3σ at trend values of ~90 N);
* *velocity* — the velocity law [000 Eq. 8] at 80–130 N × 0.5–15 mm/s × 3 repeats.

The two published laws are fitted to different views of the paper's data and do not both
hold exactly in one data set (docs/teststand.md), hence two campaigns.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flowtwin.profiles import Roller, load_rollers
from flowtwin.teststand import (
    CampaignAnalysis,
    DriveUnderTest,
    Procedure,
    Record,
    SlipLaw,
    analyse_campaign,
    analyse_records,
    simulate_campaign,
)

__all__ = ["MAX_FORCE_SCATTER", "STAND_K_P", "Campaign", "ReproContext"]

#: Slip offset of the test stand in [000 Fig. 9a]: s = 0.33 %/N·F_f + 0.63 %.
STAND_K_P = 0.0063
#: Relative per-record scatter of the maximum feed force (module docstring).
MAX_FORCE_SCATTER = 0.08
#: The stand stops at 0.05 mm/s; at the slowest speed (0.5 mm/s) that is 90 % slip. A
#: record whose slip reaches this before the maximum feed force ends by complete slip.
_STALL_SLIP_AT_SLOWEST = 0.9


@dataclass(frozen=True)
class Campaign:
    """A simulated campaign of one roller and its evaluation.

    Attributes
    ----------
    roller
        The roller of [000] on the stand.
    drive
        The drive model that was simulated.
    records
        The records.
    analysis
        The evaluation (fits of Eqs. 6, 8 and the maximum force).
    """

    roller: Roller
    drive: DriveUnderTest
    records: tuple[Record, ...]
    analysis: CampaignAnalysis


@dataclass
class ReproContext:
    """Cache of the inputs shared by the claims of one run.

    Attributes
    ----------
    seed
        Base seed of every random number of the run.
    """

    seed: int = 2021
    _rollers: dict[int, Roller] = field(default_factory=dict, repr=False)
    _campaigns: dict[tuple[str, int], Campaign] = field(default_factory=dict, repr=False)

    @property
    def rollers(self) -> dict[int, Roller]:
        """The seven rollers of [000] (``flowtwin/data/rollers.toml``)."""
        if not self._rollers:
            self._rollers.update(load_rollers())
        return self._rollers

    def grinding_range_n(self, number: int) -> tuple[float, float]:
        """Pinch forces (of the paper's grid) where roller ``number`` fails by grinding.

        Where Table 3's slip law reaches 90 % slip (the stall at 0.5 mm/s) below the
        maximum feed force of Figs. 4–8, a record ends by complete slip and its maximum is
        not the maximum of the curve (roller #4 above ~110 N, roller #2 at 10 N).

        Returns
        -------
        (low, high)
            Smallest and largest such pinch force, N.
        """
        drive = DriveUnderTest.from_roller(self.rollers[number])
        fp = np.array(Procedure().pinch_forces_n)
        slip = STAND_K_P + drive.slip_gradient_per_n(fp, 0.5) * drive.max_feed_force_n(fp) \
            * (1.0 + 2.0 * MAX_FORCE_SCATTER)
        ok = fp[slip < _STALL_SLIP_AT_SLOWEST]
        return float(ok.min()), float(ok.max())

    def pinch_campaign(self, number: int) -> Campaign:
        """The pinch-force-law campaign of roller ``number`` (module docstring)."""
        key = ("pinch", number)
        if key not in self._campaigns:
            roller = self.rollers[number]
            drive = DriveUnderTest.from_roller(roller, law=SlipLaw.PINCH, k_p=STAND_K_P,
                                               max_force_scatter=MAX_FORCE_SCATTER)
            records = simulate_campaign(drive, seed=self.seed * 100 + number)
            analysis = analyse_campaign(analyse_records(records),
                                        max_force_pinch_range_n=self.grinding_range_n(number))
            self._campaigns[key] = Campaign(roller, drive, records, analysis)
        return self._campaigns[key]

    def velocity_campaign(self, number: int) -> Campaign:
        """The velocity-law campaign of roller ``number`` at 80–130 N (module docstring)."""
        key = ("velocity", number)
        if key not in self._campaigns:
            roller = self.rollers[number]
            drive = DriveUnderTest.from_roller(roller, law=SlipLaw.VELOCITY, k_p=STAND_K_P)
            proc = Procedure(pinch_forces_n=(80.0, 90.0, 100.0, 110.0, 120.0, 130.0))
            records = simulate_campaign(drive, seed=self.seed * 100 + 50 + number,
                                        procedure=proc)
            self._campaigns[key] = Campaign(roller, drive, records,
                                            analyse_campaign(analyse_records(records)))
        return self._campaigns[key]
