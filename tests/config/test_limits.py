"""Limits and criteria check themselves when built, from Python as from a file: a ``nan``,
an ``inf``, a misspelt comparator or a reversed range never reaches judging."""

from __future__ import annotations

import math

import pytest

from bench.acceptance.criteria import Criterion, Limit, MonteCarlo, judge_value
from bench.acceptance.verdict import Verdict
from bench.errors import ConfigError
from bench.scoring.windows import WindowSpec

NAN, INF = math.nan, math.inf


@pytest.mark.parametrize(
    "args,key,text",
    [
        (("at_most", None, NAN), "at_most", "finite"),
        (("within", None, NAN), "within", "finite"),
        (("at_most", None, INF), "at_most", "finite"),
        (("at_least", -INF, None), "at_least", "finite"),
        (("in_range", NAN, 3.0), "in_range", "finite"),
        (("in_range", 1.0, INF), "in_range", "finite"),
        (("in_range", 5.0, 1.0), "in_range", "low < high"),
        (("in_range", 2.0, 2.0), "in_range", "low < high"),
        (("within", None, -1.0), "within", "non-negative"),
        (("at_mots", None, 6.0), "comparator", "unknown comparator 'at_mots'"),
        (("At_Most", None, 6.0), "comparator", "unknown comparator"),
        (("at_most", None, None), "at_most", "finite high bound"),
        (("at_most", 1.0, 6.0), "at_most", "takes no low bound"),
        (("at_least", None, 6.0), "at_least", "finite low bound"),
        (("at_most", None, "6"), "at_most", "finite"),
        (("at_most", None, True), "at_most", "finite"),
    ],
)
def test_a_bad_limit_cannot_be_built(args, key, text):
    with pytest.raises(ConfigError) as info:
        Limit(*args)
    assert info.value.key == key and text in info.value.reason


def test_good_limits_build():
    assert Limit("at_most", high=10.0).high == 10.0
    assert Limit("within", high=0.0).high == 0.0
    assert Limit("in_range", -1.0, 1.0).low == -1.0
    assert Limit("at_least", low=0).low == 0


@pytest.mark.parametrize(
    "kwargs,key,text",
    [
        ({"mode": "percentile", "percentile": NAN, "confidence": 0.9}, "monte_carlo.percentile", "between 0 and 100"),
        ({"mode": "percentile", "percentile": 100.0, "confidence": 0.9}, "monte_carlo.percentile", "between 0 and 100"),
        ({"mode": "percentile", "percentile": 0.0, "confidence": 0.9}, "monte_carlo.percentile", "between 0 and 100"),
        ({"mode": "percentile", "percentile": 95.0, "confidence": 1.0}, "monte_carlo.confidence", "between 0 and 1"),
        ({"mode": "percentile", "percentile": 95.0, "confidence": NAN}, "monte_carlo.confidence", "between 0 and 1"),
        ({"mode": "percentile", "percentile": 95.0}, "monte_carlo.confidence", "needs confidence"),
        ({"mode": "pass_runs", "pass_runs": 0}, "monte_carlo.pass_runs", ">= 1"),
        ({"mode": "pass_runs", "pass_runs": 2.5}, "monte_carlo.pass_runs", "an integer"),
        ({"mode": "pass_runs"}, "monte_carlo.pass_runs", "needs pass_runs"),
        ({"mode": "aggregate", "aggregate": "average"}, "monte_carlo.aggregate", "expected one of mean"),
        ({"mode": "each", "pass_runs": 3}, "monte_carlo.pass_runs", "takes no pass_runs"),
        ({"mode": "every"}, "monte_carlo", "unknown mode 'every'"),
    ],
)
def test_a_bad_monte_carlo_rule_cannot_be_built(kwargs, key, text):
    with pytest.raises(ConfigError) as info:
        MonteCarlo(**kwargs)
    assert info.value.key == key and text in info.value.reason


def _criterion(limit: Limit | None = None, **kw) -> Criterion:
    limit = limit or Limit("at_most", high=10.0)
    return Criterion("c", ("R",), "accuracy.horizontal.rms", WindowSpec(), limit, "m", "length", **kw)


@pytest.mark.parametrize(
    "kwargs,key,text",
    [
        ({"marginal": NAN}, "marginal", "finite non-negative band"),
        ({"marginal": -1.0}, "marginal", "finite non-negative band"),
        ({"marginal_relative": INF}, "marginal_relative", "finite non-negative band"),
        ({"marginal": 1.0, "marginal_relative": 0.1}, "marginal", "not both"),
        ({"relative_to": "b"}, "relative_to", "another variant"),
        ({"variant": "a", "relative_to": "a"}, "relative_to", "another variant"),
        ({"limit": "at_most 10 m"}, "limit", "expected a Limit"),
        ({"monte_carlo": "each"}, "monte_carlo", "expected a MonteCarlo"),
    ],
)
def test_a_bad_criterion_cannot_be_built(kwargs, key, text):
    with pytest.raises(ConfigError) as info:
        _criterion(**kwargs)
    assert info.value.key == key and text in info.value.reason


def test_a_percentile_bound_of_a_range_cannot_be_built():
    mc = MonteCarlo("percentile", percentile=95.0, confidence=0.9)
    with pytest.raises(ConfigError, match="not in_range"):
        _criterion(Limit("in_range", 0.0, 1.0), monte_carlo=mc)


def test_a_limit_bypassing_its_checks_is_judged_error_never_pass():
    """Even a Limit forced past __post_init__ cannot turn into a PASS."""
    limit = Limit("at_most", high=1.0)
    object.__setattr__(limit, "high", NAN)
    assert judge_value(limit, 0.0, 0.5)[0] is Verdict.ERROR
    within = Limit("within", high=1.0)
    object.__setattr__(within, "high", NAN)
    assert judge_value(within, 0.0, 0.5)[0] is Verdict.ERROR


# -- the same checks, from a case file, name the file and the key -----------------------------
@pytest.mark.parametrize(
    "old,new,key,text",
    [
        ('at_most = "6 m"', 'in_range = ["6 m", "1 m"]', "criterion[0].in_range", "low < high"),
        ('at_most = "6 m"', 'within = "-1 m"', "criterion[0].within", "non-negative"),
        ('at_most = "6 m"', 'at_most = "6 m"\nmonte_carlo = { percentile = nan, confidence = 0.9 }',
         "criterion[0].monte_carlo.percentile", "finite"),
        ('at_most = "6 m"', 'at_most = "6 m"\nmonte_carlo = { percentile = 95, confidence = nan }',
         "criterion[0].monte_carlo.confidence", "finite"),
        ('marginal = "0.5 m"', "marginal_relative = inf", "criterion[0].marginal_relative", "finite"),
    ],
)
def test_a_case_file_names_the_criterion_key(write, old, new, key, text):
    from bench.acceptance.case import load_case
    from tests.config.conftest import base_case

    path = write("case.toml", base_case().replace(old, new))
    with pytest.raises(ConfigError) as info:
        load_case(path)
    assert info.value.file == str(path) and info.value.key == key and text in info.value.reason
