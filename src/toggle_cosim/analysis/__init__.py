"""Analysis of traces: where the result is checked against the funnel, tolerance discovery,
CI reports (JUnit XML, Markdown), solver statistics and trace file formats."""
