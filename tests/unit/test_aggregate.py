import pandas as pd

from avoa_pipeline import aggregate, fit, problem


def _record(cfg, algorithm="avoa", seed=1):
    budget = fit.budget_from(cfg, pop_size=4, iterations=2)
    return fit.run(cfg, problem.build(cfg, 1, 2), algorithm, seed, budget)


def test_empty_runs_table_has_the_columns_and_order_of_a_real_one(cfg):
    # run_row_columns restates run_row's layout for pairs a config does not run; an empty pair
    # and a run pair are concatenated by the report, so the two must never drift apart
    row = aggregate.run_row(_record(cfg))
    assert list(row) == aggregate.run_row_columns()
    empty = aggregate.empty_runs()
    runs, _ = aggregate.collect([_record(cfg), _record(cfg, "gto", 2)])
    assert list(empty.columns) == list(runs.columns)
    both = pd.concat([empty, runs], ignore_index=True)
    assert both.dtypes.equals(runs.dtypes)
