"""Signals: what a plant input is over time (a constant, a profile, a table), defined once as
typed, pure data (`definitions`), written in a scenario as `schema` says, read from CSV by
`tables`. The master samples a signal at every communication point (`definitions.sample`)."""
