"""The process isolation of runs: each run in a forked child (`supervision`), several at once
(`supervised_batch`), a child that keeps a plant loaded for request after request
(`plant_host`), and why a child ended, in words (`exit_reasons`)."""
