"""Virtual filament-drive test stand and the evaluation of test-stand records [000 §3–4].

docs/spec.md §3.8. The stand runs the measurement procedure of Nienhaus et al. [000 §3] on a drive
model (:mod:`~flowtwin.teststand.model`, :mod:`~flowtwin.teststand.simulate`) and writes
records in a CSV schema a real stand can also produce (:mod:`~flowtwin.teststand.records`,
docs/teststand.md). The evaluation (:mod:`~flowtwin.teststand.analysis`,
:mod:`~flowtwin.teststand.fits`, :mod:`~flowtwin.teststand.report`) turns records —
simulated or real — into the maximum feed force per record, the slip gradient with its
``R²``, ``k_s`` and ``k_∞`` [000 Eq. 6], ``a, b, c`` [000 Eq. 8], ``F_p,min`` [000 Eq. 9]
and the 2nd-order maximum-force fit [000 Figs. 4–8], each with its uncertainty.

Quick start::

    from flowtwin.profiles import load_rollers
    from flowtwin.teststand import (DriveUnderTest, SlipLaw, simulate_campaign,
                                    analyse_records, analyse_campaign, compare_with_roller)

    roller = load_rollers()[3]
    drive = DriveUnderTest.from_roller(roller, law=SlipLaw.PINCH, k_p=0.0063)
    records = simulate_campaign(drive, seed=1)           # 15 × 6 × 3 = 270 records
    analysis = analyse_campaign(analyse_records(records))
    for check in compare_with_roller(analysis, roller):
        print(check.name, check.published, check.recovered, check.passed)
"""

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

if TYPE_CHECKING:
    from flowtwin.teststand.analysis import (
        RecordResult,
        SlipRegression,
        analyse_record,
        analyse_records,
        loading_phase,
        slip_regression,
    )
    from flowtwin.teststand.fits import (
        MaxForceFit,
        PinchLawFit,
        VelocityLawFit,
        fit_max_feed_force,
        fit_pinch_law,
        fit_velocity_law,
        r_squared_histogram,
    )
    from flowtwin.teststand.model import DriveUnderTest, Instrument, Procedure
    from flowtwin.teststand.records import (
        COLUMNS,
        SCHEMA_VERSION,
        ColumnSpec,
        Record,
        RecordKey,
        read_records_csv,
        write_records_csv,
    )
    from flowtwin.teststand.report import (
        CampaignAnalysis,
        ParameterCheck,
        analyse_campaign,
        compare_with_roller,
    )
    from flowtwin.teststand.series import PAPER_PINCH_FORCES_N, PAPER_SPEEDS_MM_S, SlipLaw
    from flowtwin.teststand.simulate import simulate_campaign, simulate_record

__all__ = [
    "COLUMNS",
    "PAPER_PINCH_FORCES_N",
    "PAPER_SPEEDS_MM_S",
    "SCHEMA_VERSION",
    "CampaignAnalysis",
    "ColumnSpec",
    "DriveUnderTest",
    "Instrument",
    "MaxForceFit",
    "ParameterCheck",
    "PinchLawFit",
    "Procedure",
    "Record",
    "RecordKey",
    "RecordResult",
    "SlipLaw",
    "SlipRegression",
    "VelocityLawFit",
    "analyse_campaign",
    "analyse_record",
    "analyse_records",
    "compare_with_roller",
    "fit_max_feed_force",
    "fit_pinch_law",
    "fit_velocity_law",
    "loading_phase",
    "r_squared_histogram",
    "read_records_csv",
    "simulate_campaign",
    "simulate_record",
    "slip_regression",
    "write_records_csv",
]

# names resolve on first use (importing the package stays light)
__getattr__, __dir__ = lazy_exports(__name__, {
    "RecordResult": "flowtwin.teststand.analysis",
    "SlipRegression": "flowtwin.teststand.analysis",
    "analyse_record": "flowtwin.teststand.analysis",
    "analyse_records": "flowtwin.teststand.analysis",
    "loading_phase": "flowtwin.teststand.analysis",
    "slip_regression": "flowtwin.teststand.analysis",
    "MaxForceFit": "flowtwin.teststand.fits",
    "PinchLawFit": "flowtwin.teststand.fits",
    "VelocityLawFit": "flowtwin.teststand.fits",
    "fit_max_feed_force": "flowtwin.teststand.fits",
    "fit_pinch_law": "flowtwin.teststand.fits",
    "fit_velocity_law": "flowtwin.teststand.fits",
    "r_squared_histogram": "flowtwin.teststand.fits",
    "PAPER_PINCH_FORCES_N": "flowtwin.teststand.series",
    "PAPER_SPEEDS_MM_S": "flowtwin.teststand.series",
    "DriveUnderTest": "flowtwin.teststand.model",
    "Instrument": "flowtwin.teststand.model",
    "Procedure": "flowtwin.teststand.model",
    "SlipLaw": "flowtwin.teststand.series",
    "COLUMNS": "flowtwin.teststand.records",
    "SCHEMA_VERSION": "flowtwin.teststand.records",
    "ColumnSpec": "flowtwin.teststand.records",
    "Record": "flowtwin.teststand.records",
    "RecordKey": "flowtwin.teststand.records",
    "read_records_csv": "flowtwin.teststand.records",
    "write_records_csv": "flowtwin.teststand.records",
    "CampaignAnalysis": "flowtwin.teststand.report",
    "ParameterCheck": "flowtwin.teststand.report",
    "analyse_campaign": "flowtwin.teststand.report",
    "compare_with_roller": "flowtwin.teststand.report",
    "simulate_campaign": "flowtwin.teststand.simulate",
    "simulate_record": "flowtwin.teststand.simulate",
})
