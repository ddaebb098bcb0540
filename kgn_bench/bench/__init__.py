"""The closed-loop harness: typed records, the trial loop with its selector and executor, the runner,
statistics, reports, bundles, the regression check and perf."""
