"""The experiments: one closed-loop impact trial with the QP (``trial``), the campaign of every
robot (``campaign``, its Table I ``campaign_table``, its figures ``campaign_figures``), the highest feasible contact speed
(``max_speed_search``, its figure ``max_speed_figure``), ``impactqp run`` on a robot (``run``), the
diagnosis report, the video with the robot's meshes (``video``), the joint velocities around an
impact (``impact_figure``), the G1's closed form checked against simulation (``stance_check``),
the frictional impact law against MuJoCo's wall (``oblique``) and the feasibility maps (``sweep``); above them the command line (``cli``) and
the benchmarks (``bench``).

Its names are exported lazily (PEP 562): the command line imports this file first and must stay
quick to start (``scenarios.cli``).
"""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_EXPORTS = {
    "TrialRunner": "trial",
    "TrialPool": "trial",
    "Campaign": "campaign",
    "CampaignPlan": "campaign",
    "CampaignTrials": "campaign",
    "Table1": "campaign_table",
    "MaxSpeedSearch": "max_speed_search",
    "MaxSpeedReport": "max_speed_search",
    "RunRequest": "run",
    "write_report": "diagnosis_report",
    "render_trial_video": "video",
    "write_trial_video": "video",
    "write_velocity_figure": "impact_figure",
    "write_max_speed_figure": "max_speed_figure",
    "run_stance_trials": "campaign",
    "search_stance": "max_speed_search",
    "check_against_simulation": "stance_check",
    "run_oblique_study": "oblique",
}
_EXPORTS = {name: f"{__name__}.{module}" for name, module in _EXPORTS.items()}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
