"""Control laws, each defined once in pure Python (`laws`, `nominal`) and compiled to C from
that definition (`translate`, `kernel`)."""
