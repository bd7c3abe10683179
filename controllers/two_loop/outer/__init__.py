"""The outer loop: the SPMM OCP and its planners, C/GMRES and Ipopt (docs/method.md §2-§5)."""
