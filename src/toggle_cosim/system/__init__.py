"""A system: the master's unit (components, connections, what to record) and the order that steps it."""
