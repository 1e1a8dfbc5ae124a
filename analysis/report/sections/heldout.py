"""Section: named agents with a held-out partner population (Carroll et al.'s PPO_SP and PPO_BC with H_proxy)."""

from __future__ import annotations

from analysis.report.context import Context
from analysis.report.formatting import fmt_ci, md_table
from analysis.report.verdicts import Difference
from analysis.summaries import seed_means, summarise, unpaired_difference

# Carroll et al. (NeurIPS 2019), Section 5 and Figure 4: with the human proxy, the agent trained with a BC model
# (PPO_BC) scores higher than the self-play agent (PPO_SP) on every layout, while PPO_SP scores far higher with
# itself. The paper gives the figure's bars, not numbers, so the report checks the ordering, not values.
CARROLL = "Carroll et al. 2019, Fig. 4: PPO_BC + H_proxy above PPO_SP + H_proxy on every layout"


def heldout_section(ctx: Context) -> str:
    """Each agent's mean score with the held-out partners (seed as the unit) and the plan's claims "A beats B"."""
    lines = ["## Held-out partners", ""]
    if ctx.heldout.empty:
        lines.append("No held-out evaluation (`<game>/heldout.csv`) found.")
        return "\n".join(lines)
    lines += [
        "Each agent's seeds play every member of the held-out population (on Overcooked: the human proxies H_proxy, "
        "cloned from people none of the agents trained with), scored on soups alone. Per seed the mean over the held-out "
        'members, then the 95% t-interval over seeds. The agents are trained independently, so a claim "A beats B" is '
        "judged on the difference of their seed means with Welch's interval (no pairing); the verdict rule is the "
        "report's (supported when the whole interval is above 0).",
        "",
    ]
    for game, frame in ctx.heldout.groupby("game"):
        plan = ctx.plans.get(game, {}).get("heldout", {})
        per_seed = seed_means(frame, ["agent"], "mean_return")
        table = summarise(per_seed, ["agent"], "mean_return")
        partners = plan.get("partners", "the held-out population")
        rows = [[r.agent, fmt_ci(r.mean, r.lo, r.hi, r.n, 1)] for r in table.itertuples()]
        lines += [
            f"### {game}: with every member of `{partners}`",
            "",
            md_table(["agent", "mean score [95% CI] (seeds)"], rows),
            "",
        ]
        claims = []
        for a, b in plan.get("claims", []):
            scores = [per_seed.loc[per_seed["agent"] == x, "mean_return"] for x in (a, b)]
            diff = Difference(a, b, *unpaired_difference(*scores))
            claims.append([f"{a} beats {b}", diff.verdict, diff.text(1)])
        if claims:
            lines += [f"Claims declared in the plan ({CARROLL}):", "", md_table(["claim", "verdict", "evidence"], claims), ""]
    return "\n".join(lines)
