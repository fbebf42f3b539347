"""Model choice, as components the estimators compose: each returns what it chose and why.

* :mod:`~avbench.estimators.selection.evidence` -- a term's evidence: the boundary-corrected
  (chi-bar-squared) p-value of its likelihood ratio, and whether it is present at a level;
* :mod:`~avbench.estimators.selection.profile` -- boundary-aware profile-likelihood intervals and the
  choice of the domain an interval is read in;
* :mod:`~avbench.estimators.selection.elimination` -- backward elimination of terms by a penalised
  likelihood, and model weights by an information criterion.

The modules import the contract's leaves and numpy/scipy only, never an estimator family.
"""
