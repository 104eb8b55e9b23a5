"""The execution and its kinds: a system's components (slaves: FMI 2.0/3.0 FMUs, native
controllers, Python controllers) stepped by one plan, in Python (`algorithm`) or in C
(`system_loop`), with checkpoint retries (`system_retry`), a work budget (`budget`) and an
instance pool (`instance_pool`). Nothing here knows a scenario, a process or a file of results."""
