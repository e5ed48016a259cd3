"""The full model on the package's sample dataset (8 cables, rotating): the mass within 4 std of
the truth in meta.toml, read through the typed estimates (issue 36)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.mark.slow  # over 20 s on 2 cores: with the slow tests (CI runs them all)
def test_full_model_identifies_the_sample_truth(sample_dataset):
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset

    ds = read_dataset(sample_dataset)
    rep = identify_dataset(ds, model="full", bound=False)
    m = rep.parameters()["m"]
    assert m.unit == "kg"
    assert abs(m.value - ds.truth["mass"]) < 4 * m.std + 1e-3
    names, x, cov, _ = rep.estimates()  # the untyped view holds the same numbers
    k = list(names).index("m")
    assert (m.value, m.std) == (float(x[k]), float(np.sqrt(cov[k, k])))
