"""Model choice, as components the estimators compose: each returns what it chose and why.

* :mod:`~avbench.estimators.selection.evidence` -- a term's evidence: the boundary-corrected
  (chi-bar-squared) p-value of its likelihood ratio, and whether it is present at a level;
* :mod:`~avbench.estimators.selection.profile` -- boundary-aware profile-likelihood intervals and the
  choice of the domain an interval is read in;
* :mod:`~avbench.estimators.selection.elimination` -- backward elimination of terms by a penalised
  likelihood, and model weights by an information criterion;
* :mod:`~avbench.estimators.selection.scales` -- the shortest AV scale a model fits (GMWM's ``min_m``);
* :mod:`~avbench.estimators.selection.lines` -- the test for a spectral line (a hidden periodicity)
  and the choice to model it;
* :mod:`~avbench.estimators.selection.resonance` -- a band that stands out of the spectrum, and the
  choice to model it as a resonance;
* :mod:`~avbench.estimators.selection.averaging` -- model averaging by Akaike weights over the
  terms a fit cannot tell from absent, and the weights of models by an information criterion;
* :mod:`~avbench.estimators.selection.bias_model` -- Gauss-Markov or flicker bias instability, by
  the models' AIC weights;
* :mod:`~avbench.estimators.selection.bounds` -- the upper bounds the record's AV allows a term it
  does not resolve;
* :mod:`~avbench.estimators.selection.choices` -- each choice as the typed ``ModelChoice`` a fit
  reports, with the parts that carry the record's unit;
* :mod:`~avbench.estimators.selection.shared` -- the choices made once per axis and taken by every method
  that would make them alike on the same values.

The modules import the contract's leaves and numpy/scipy only, never an estimator family.
"""
