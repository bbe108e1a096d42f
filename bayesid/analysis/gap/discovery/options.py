"""The options of structure discovery (:class:`DiscoveryOptions`): the term library searched,
the ensemble that selects among its terms and the fits that confirm them."""

from __future__ import annotations

from dataclasses import dataclass

from ....models.library import MAX_ORDER

__all__ = ["DOFS", "DiscoveryOptions"]

#: The degrees of freedom structure discovery may search: surge, sway and yaw forces.
DOFS = ("X", "Y", "N")


@dataclass(frozen=True)
class DiscoveryOptions:
    """What structure discovery searches and how it decides (:func:`~bayesid.analysis.gap.discovery.discover`).

    Parameters
    ----------
    max_order : int, default 3
        Highest number of factors of a candidate term (ship; a submarine term has at most two
        velocity factors by its prime form).
    dofs : tuple of str, default ("Y", "N")
        The degrees of freedom searched (``"X"``, ``"Y"``, ``"N"``).
    n_models : int, default 100
        Bootstrap models of the ensemble.
    threshold : float, default 0.1
        STLSQ threshold on the normalised coefficients: a term must carry this share of the
        projected output residual's RMS to stay in a model.
    block_s : float, default 10.0
        Block length of the block bootstrap, s.
    min_probability : float, default 0.5
        Group inclusion probability from which a group is refitted (confirmation).
    max_candidates : int, default 6
        At most this many groups are refitted (the most probable).
    group_cos : float, default 0.95
        |cosine| of two candidates' force columns from which they form a collinear group.
    trim_s : float, default 2.0
        Seconds dropped at either end of each track (smoothing edges).
    lowpass_s : float, default 2.0
        Moving-average window applied alike to the missing forces and the columns, s.
    ridge : float, default 0.01
        Ridge weight per sample of the normalised regression (collinear columns).

    max_nfev : int, default 60
        Least-squares iterations of each confirmation fit.
    n_alternatives : int, default 0
        Further candidates refitted beside the selected ones: up to twice this many terms the
        ensemble selects (inclusion >= ``min_probability``) that a collinear group member stood
        for, and per searched degree of freedom this many best by the score test of the
        linearised problem (the share of the projected residual one column explains alone),
        whatever their group and inclusion probability: the structures the runs may not
        separate from the selected term (:func:`~.confirmation.alternatives`); and this many
        candidates the selection set aside as mimicked, one per mimic
        (:func:`~.selection.mimicked_refits`: a constant yaw moment ``N0`` hidden in the
        neutral rudder angle ``dR0``), kept like any candidate when they pass the kept test. 0
        (the default until the test suite's budget is re-measured with it): none; 2 is the
        setting measured.
    compare : tuple of str, default ()
        Terms of the library refitted and judged whatever the selection says: the kept terms
        and alternatives of an earlier round, compared again once a run designed to separate
        them is added (issue 49's loop). Without them a fresh selection on the new runs may
        refit none of the earlier alternatives, and name a new surrogate alone. A name that
        is not a term of the library searched raises ``ValueError`` in :func:`discover`.

    Raises
    ------
    ValueError
        An option out of range (named).
    """

    max_order: int = 3
    dofs: tuple = ("Y", "N")
    n_models: int = 100
    threshold: float = 0.1
    block_s: float = 10.0
    min_probability: float = 0.5
    max_candidates: int = 6
    group_cos: float = 0.95
    trim_s: float = 2.0
    lowpass_s: float = 2.0
    ridge: float = 0.01
    max_nfev: int = 60
    n_alternatives: int = 0
    compare: tuple = ()

    def __post_init__(self):
        if not 1 <= int(self.max_order) <= MAX_ORDER:
            raise ValueError(f"max_order must be 1..{MAX_ORDER}, got {self.max_order}")
        bad = [d for d in self.dofs if d not in DOFS]
        if bad or not self.dofs:
            raise ValueError(f"dofs must be a non-empty subset of {DOFS}, got {self.dofs}")
        if int(self.n_models) < 2:
            raise ValueError(f"n_models must be >= 2, got {self.n_models}")
        if not 0 < self.min_probability <= 1:
            raise ValueError(f"min_probability must be in (0, 1], got {self.min_probability}")
        if not 0 < self.group_cos <= 1:
            raise ValueError(f"group_cos must be in (0, 1], got {self.group_cos}")
        if int(self.n_alternatives) < 0:
            raise ValueError(f"n_alternatives must be >= 0, got {self.n_alternatives}")
        if not self.threshold >= 0 or not self.block_s > 0 or not self.trim_s >= 0:
            raise ValueError("threshold and trim_s must be >= 0 and block_s > 0")
        object.__setattr__(self, "dofs", tuple(self.dofs))
        if isinstance(self.compare, str):
            raise ValueError(f"compare must be a sequence of term names, got the string {self.compare!r}")
        object.__setattr__(self, "compare", tuple(dict.fromkeys(str(n) for n in self.compare)))
