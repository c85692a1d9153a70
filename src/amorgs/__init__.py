"""amorgs — amortized global search of optimal spacecraft trajectories.

A reproducible workbench: multi-start local optimisation of a parameterised family of low-thrust
transfers (CR3BP, CasADi + IPOPT) and of De Jong's 5th function, β-filtering of the optima, structure
analysis, conditional generative models (CVAE with Gaussian-mixture prior, LSTM) and the warm-start
ablation of Li et al., "Global Search of Optimal Spacecraft Trajectories using Amortization and Deep
Generative Models".
"""

__version__ = "0.1.0"
