"""Comparison baselines for the two-loop controller (METHOD.md §8, result 3).

``ipopt_outer``: the outer-loop OCP of C/GMRES solved by Ipopt (CasADi), warm-started.
``ipopt_nmpc``: the two-loop controller with that outer solver (factory only; the
lead registers it). Both import CasADi lazily so ``import controllers.baselines``
stays light when CasADi is not installed.
"""
