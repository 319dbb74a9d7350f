"""CECO nonlinear MPC strategies (CasADi) and the baseline PI climate controller for ceco."""
