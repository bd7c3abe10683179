"""What the paper reports as numbers, to be shown beside ours (docs/paper.md).

The paper's simulation section gives few numbers in its text (its figures are plots):
where things happen on the straight road, and the variances of the two solvers' time
per step. Its experiment section gives the cost of the whole control step on its
test bench. Everything else it states as a direction (larger, slower, lower), which is
what our findings test.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PaperValues:
    """The paper's numbers, SI units.

    ``obstacle_ahead_m``: the stalled car's distance from the start on the straight road
    [m]; ``window_entry_m``: distance travelled when it enters the optimisation window
    (the horizon's far end reaches it) [m]; ``chatter_from_m`` / ``chatter_to_m``: the
    stretch of J1's high-frequency steering [m] (Fig. 10); ``ipopt_var_s2`` /
    ``cgmres_var_s2``: variance of the time per step of the iterative solver and of
    C/GMRES [s²] (Fig. 15); ``ipopt_rise_from_m`` / ``ipopt_rise_to_m``: where the
    iterative solver's time rises as the obstacle enters its horizon [m];
    ``experiment_step_s``: the whole control logic (outer and inner loop) per step on
    the scaled-vehicle bench [s] (an Intel Core i3-3220, 3.3 GHz)."""

    obstacle_ahead_m: float = 110.0
    window_entry_m: float = 46.0
    chatter_from_m: float = 44.0
    chatter_to_m: float = 52.0
    ipopt_var_s2: float = 0.0242
    cgmres_var_s2: float = 1.8347e-5
    ipopt_rise_from_m: float = 80.0
    ipopt_rise_to_m: float = 90.0
    experiment_step_s: float = 1.12e-3

    @property
    def var_ratio(self) -> float:
        """Ipopt's variance over C/GMRES's [-]."""
        return self.ipopt_var_s2 / self.cgmres_var_s2


PAPER = PaperValues()
