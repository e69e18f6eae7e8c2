"""The genetic algorithm that learns a keyframe query ([MBS09] §6, docs/method.md §6).

Individuals are keyframe queries: genes ``(position, group, mask, value)`` in template order
and gap bounds between consecutive genes. One run:

* **Initial population** of M individuals: N ~ round(Normal(3, 1)) (1 ≤ N ≤ 5, [MR06]'s
  "two to five" keyframes) distinct template columns q, each giving one keyframe: the
  column of the *strict* (δ = 0) quantized template over one group, chosen at random among
  the groups where that column fixes some feature ([MBS09]: "randomly pick N columns of
  X"); gap bounds from the column distance d with a random tolerance, dmin = ⌈s·d⌉,
  dmax = ⌊d/s⌋, s ~ U(0.5, 0.9).
* **Each generation**: r parents by stochastic universal sampling (fitness-proportional,
  uniform when every fitness is 0); every pair of parents recombines into one offspring (a
  random subset of each parent's keyframes, each kept with probability ½, merged in
  template order; new gap bounds as at initialization) → r(r−1)/2 offspring; each
  offspring gets one random mutation: add or remove a keyframe; specialize a wildcard or
  generalize a fixed entry; widen or narrow one gap bound. A wildcard is only specialized
  where the soft template is consistent (value ≤ δ_s or ≥ 1 − δ_s, δ_s = 0.05, the
  annotation quantization), to that value: keyframes stay within what the class's
  examples agree on, which is what carries over to new performers.
* **Survivors**: the M fittest distinct individuals of parents ∪ offspring. Among equally
  fit ones, the one fixing fewer feature entries ranks first (then the older one): on
  training clips many queries are equally fit, and without this parsimony rule the
  population drifts into ever more specific keyframes that the training clips happen to
  share but new performers do not.
* After G generations the fittest individual wins.

Everything random comes from one :class:`numpy.random.Generator`, so a run is a pure
function of its seed; fitness (:mod:`mtanno.keyframes.fitness`) is deterministic. Defaults
are [MBS09]'s: M = 50, r = 5, G = 100, β = 2. ``docs/keyframes.md`` gives the evidence for
the choices that go beyond [MBS09].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mtanno.errors import MtannoError
from mtanno.keyframes.fitness import Bounds, Gene, Score, TrainingSet

__all__ = ["GAParams", "GARun", "Problem", "run_ga"]


@dataclass(frozen=True)
class GAParams:
    """Parameters of one GA run (defaults: [MBS09] §6–7)."""

    population: int = 50
    """M, individuals that survive each generation."""
    parents: int = 5
    """r, parents drawn per generation (r(r−1)/2 offspring)."""
    generations: int = 100
    """G, generations per run."""
    beta: float = 2.0
    """β of the fitness F_β (β > 1 weighs recall above precision)."""
    mean_keyframes: float = 3.0
    """Mean of the Normal that draws an initial individual's number of keyframes N."""
    sd_keyframes: float = 1.0
    """Its standard deviation."""
    max_keyframes: int = 5
    """Most keyframes an individual may hold (at initialization and after mutation)."""
    stiffness: tuple[float, float] = (0.5, 0.9)
    """Range of s ~ U(lo, hi) for gap bounds dmin = ⌈s·d⌉, dmax = ⌊d/s⌋ (d in frames)."""
    specialize_delta: float = 0.05
    """δ_s: a wildcard is specialized only where the soft template is ≤ δ_s or ≥ 1 − δ_s."""
    mismatches: int = 0
    """Fixed entries a keyframe may get wrong (0, 1 or 2; see ``fitness.keyframe_tolerance``)."""

    def __post_init__(self):
        for name in ("population", "parents", "generations", "max_keyframes"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise MtannoError(f"GA {name} must be a positive integer, got {v!r}")
        if self.parents < 2:
            raise MtannoError("GA needs at least 2 parents per generation")
        lo, hi = self.stiffness
        if not 0 < lo <= hi <= 1:
            raise MtannoError(f"GA stiffness range must satisfy 0 < lo ≤ hi ≤ 1, got "
                              f"{self.stiffness}")
        if self.mismatches not in (0, 1, 2):
            raise MtannoError(f"GA mismatches must be 0, 1 or 2, got {self.mismatches!r}")
        if not 0 <= self.specialize_delta < 0.5:
            raise MtannoError("specialize_delta must lie in [0, 0.5)")
        if not (self.beta > 0 and math.isfinite(self.beta)):
            raise MtannoError(f"beta must be a positive number, got {self.beta!r}")

    def as_dict(self) -> dict:
        return {"population": self.population, "parents": self.parents,
                "generations": self.generations, "beta": self.beta,
                "mean_keyframes": self.mean_keyframes, "sd_keyframes": self.sd_keyframes,
                "max_keyframes": self.max_keyframes, "stiffness": list(self.stiffness),
                "specialize_delta": self.specialize_delta, "mismatches": self.mismatches}


@dataclass
class Problem:
    """What a run learns from: the class's template and the training clips.

    ``strict`` is the (features × K) template quantized with δ = 0 (0, 1, 0.5), ``soft``
    the unquantized template (its values decide specializations); ``group_rows[g]`` are
    the feature rows of group g (bit k of a gene's mask = ``group_rows[g][k]``);
    ``positives`` marks the class's clips in ``training``; fitness counts only the clips
    ``within`` (default all; the others are held out for validation).
    """

    strict: np.ndarray
    soft: np.ndarray
    group_rows: list[np.ndarray]
    training: TrainingSet
    positives: np.ndarray
    within: np.ndarray | None = None

    def __post_init__(self):
        if self.strict.shape != self.soft.shape:
            raise MtannoError("strict and soft templates differ in shape")
        inside = self.positives if self.within is None else self.positives & self.within
        if not inside.any():
            raise MtannoError("no positive training clips")
        if self.within is None and self.positives.all() or \
                self.within is not None and (self.positives | ~self.within).all():
            raise MtannoError("no negative training clips (the GA needs clips of at least "
                              "two classes)")

    @property
    def K(self) -> int:
        return self.strict.shape[1]


Individual = tuple[tuple[Gene, ...], tuple[Bounds, ...]]


@dataclass
class GARun:
    """Result of one run: the fittest individual, its score, and per generation (0 = the
    initial population) the best and mean fitness and the mean P and R of the population."""

    genes: tuple[Gene, ...]
    gaps: tuple[Bounds, ...]
    score: Score
    history: dict[str, list[float]] = field(default_factory=dict)
    evaluations: int = 0


class _Engine:
    def __init__(self, problem: Problem, params: GAParams, rng: np.random.Generator):
        self.pb = problem
        self.p = params
        self.rng = rng
        self.cache: dict[Individual, Score] = {}
        self.n_groups = len(problem.group_rows)
        strict = problem.strict
        # per column: groups where the strict column fixes at least one feature
        self.fixed_groups = [[g for g, rows in enumerate(problem.group_rows)
                              if (strict[rows, q] != 0.5).any()] for q in range(problem.K)]

    # ----------------------------------------------------------------- pieces
    def fitness(self, ind: Individual) -> Score:
        s = self.cache.get(ind)
        if s is None:
            s = self.pb.training.score(ind[0], ind[1], self.pb.positives, self.p.beta,
                                       within=self.pb.within, mismatches=self.p.mismatches)
            self.cache[ind] = s
        return s

    def gene_at(self, q: int) -> Gene:
        """A keyframe from strict column q (1-based) over a random group fixing something
        there (any group if none does, with its most decided feature fixed)."""
        rng, pb = self.rng, self.pb
        choices = self.fixed_groups[q - 1]
        if choices:
            g = choices[int(rng.integers(len(choices)))]
        else:
            g = int(rng.integers(self.n_groups))
        rows = pb.group_rows[g]
        col = pb.strict[rows, q - 1]
        mask = value = 0
        for k, v in enumerate(col):
            if v != 0.5:
                mask |= 1 << k
                value |= int(v == 1.0) << k
        if mask == 0:
            k = int(np.argmax(np.abs(pb.soft[rows, q - 1] - 0.5)))
            mask = 1 << k
            value = int(pb.soft[rows[k], q - 1] >= 0.5) << k
        return (q, g, mask, value)

    def random_gap(self, d: int) -> Bounds:
        lo, hi = self.p.stiffness
        s = float(self.rng.uniform(lo, hi))
        return (math.ceil(s * d - 1e-9), math.floor(d / s + 1e-9))

    def gaps_for(self, genes) -> tuple[Bounds, ...]:
        return tuple(self.random_gap(genes[j + 1][0] - genes[j][0])
                     for j in range(len(genes) - 1))

    @staticmethod
    def _canon(genes) -> tuple[Gene, ...]:
        out: dict[tuple[int, int], Gene] = {}
        for g in sorted(genes, key=lambda x: (x[0], x[1])):
            out.setdefault((g[0], g[1]), g)
        return tuple(out.values())

    def initial(self) -> Individual:
        rng, K = self.rng, self.pb.K
        n = int(round(rng.normal(self.p.mean_keyframes, self.p.sd_keyframes)))
        n = max(1, min(n, self.p.max_keyframes, K))
        cols = np.sort(rng.choice(K, size=n, replace=False)) + 1
        genes = self._canon(self.gene_at(int(q)) for q in cols)
        return genes, self.gaps_for(genes)

    def recombine(self, a: Individual, b: Individual) -> Individual:
        rng = self.rng
        keep = [g for g in a[0] if rng.random() < 0.5] + [g for g in b[0] if rng.random() < 0.5]
        if not keep:
            keep = [a[0][int(rng.integers(len(a[0])))]]
        genes = list(self._canon(keep))
        while len(genes) > self.p.max_keyframes:
            genes.pop(int(rng.integers(len(genes))))
        genes = tuple(genes)
        return genes, self.gaps_for(genes)

    def mutate(self, ind: Individual) -> Individual:
        rng = self.rng
        genes, gaps = list(ind[0]), list(ind[1])
        op = int(rng.integers(3))
        if op == 2 and len(genes) == 1:
            op = 1
        if op == 0:  # add or remove a keyframe
            add = len(genes) == 1 or (len(genes) < self.p.max_keyframes and rng.random() < 0.5)
            if add:
                g = self.gene_at(int(rng.integers(1, self.pb.K + 1)))
                if any((h[0], h[1]) == (g[0], g[1]) for h in genes):
                    return ind
                genes = list(self._canon(genes + [g]))
                j = genes.index(g)
                # the new keyframe splits one gap (or extends the query at an end)
                new = []
                for i in range(len(genes) - 1):
                    if i in (j - 1, j):
                        new.append(self.random_gap(genes[i + 1][0] - genes[i][0]))
                    else:
                        new.append(gaps[i if i < j else i - 1])
                gaps = new
            else:
                j = int(rng.integers(len(genes)))
                genes.pop(j)
                if j == 0:
                    gaps.pop(0)
                elif j == len(genes):
                    gaps.pop(j - 1)
                else:  # two gaps in a row compose exactly
                    a, b = gaps[j - 1], gaps.pop(j)
                    gaps[j - 1] = (a[0] + b[0],
                                   None if a[1] is None or b[1] is None else a[1] + b[1])
        elif op == 1:  # specialize or generalize one entry
            j = int(rng.integers(len(genes)))
            q, g, mask, value = genes[j]
            rows = self.pb.group_rows[g]
            width = len(rows)
            soft = self.pb.soft[rows, q - 1]
            d = self.p.specialize_delta
            free = [k for k in range(width) if not mask >> k & 1
                    and (soft[k] <= d or soft[k] >= 1 - d)]
            fixed = [k for k in range(width) if mask >> k & 1]
            if free and (len(fixed) <= 1 or rng.random() < 0.5):
                k = free[int(rng.integers(len(free)))]
                mask |= 1 << k
                value |= int(soft[k] >= 0.5) << k
            elif len(fixed) > 1:
                k = fixed[int(rng.integers(len(fixed)))]
                mask &= ~(1 << k)
                value &= ~(1 << k)
            else:
                return ind
            genes[j] = (q, g, mask, value)
        else:  # widen or narrow one gap bound
            j = int(rng.integers(len(gaps)))
            lo, hi = gaps[j]
            d = genes[j + 1][0] - genes[j][0]
            step = int(rng.integers(1, max(1, round(0.25 * d)) + 1))
            if rng.random() < 0.5:
                lo = max(0, lo + (step if rng.random() < 0.5 else -step))
                if hi is not None and lo > hi:
                    lo = hi
            else:
                if hi is None:
                    hi = max(lo, d) + step
                else:
                    hi = max(lo, hi + (step if rng.random() < 0.5 else -step))
            gaps[j] = (lo, hi)
        return tuple(genes), tuple(gaps)

    def select(self, pop: list[Individual], fit: list[float]) -> list[int]:
        """Stochastic universal sampling of r parents (indices into ``pop``)."""
        r = self.p.parents
        total = float(sum(fit))
        if total <= 0:
            return [int(i) for i in self.rng.integers(len(pop), size=r)]
        step = total / r
        u = float(self.rng.uniform(0, step))
        cum = np.cumsum(fit)
        return [int(min(np.searchsorted(cum, u + i * step, side="right"), len(pop) - 1))
                for i in range(r)]

    # ----------------------------------------------------------------- the run
    def run(self) -> GARun:
        M = self.p.population
        pop = self._survivors([self.initial() for _ in range(M)], M)
        hist: dict[str, list[float]] = {"best": [], "mean": [], "mean_P": [], "mean_R": []}
        self._record(pop, hist)
        for _ in range(self.p.generations):
            fit = [self.fitness(i).F for i in pop]
            parents = [pop[i] for i in self.select(pop, fit)]
            offspring = []
            for a in range(len(parents)):
                for b in range(a + 1, len(parents)):
                    offspring.append(self.mutate(self.recombine(parents[a], parents[b])))
            pop = self._survivors(pop + offspring, M)
            self._record(pop, hist)
        best = pop[0]
        return GARun(best[0], best[1], self.fitness(best), hist, len(self.cache))

    def _survivors(self, inds: list[Individual], M: int) -> list[Individual]:
        seen, uniq = set(), []
        for i in inds:
            if i not in seen:
                seen.add(i)
                uniq.append(i)
        order = sorted(range(len(uniq)), key=lambda k: (-self.fitness(uniq[k]).F,
                                                        _fixed(uniq[k])))
        return [uniq[k] for k in order[:M]]

    def _record(self, pop, hist):
        sc = [self.fitness(i) for i in pop]
        hist["best"].append(sc[0].F)
        hist["mean"].append(float(np.mean([s.F for s in sc])))
        hist["mean_P"].append(float(np.mean([s.P for s in sc])))
        hist["mean_R"].append(float(np.mean([s.R for s in sc])))


def _fixed(ind: Individual) -> int:
    """Fixed (non-wildcard) entries over all keyframes: the parsimony tie-break."""
    return sum(bin(g[2]).count("1") for g in ind[0])


def run_ga(problem: Problem, *, rng: np.random.Generator | int,
           params: GAParams = GAParams()) -> GARun:
    """One run of the genetic algorithm (module docstring); ``rng`` is a Generator or a
    seed. The best fitness never decreases from one generation to the next."""
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(rng)
    return _Engine(problem, params, rng).run()
