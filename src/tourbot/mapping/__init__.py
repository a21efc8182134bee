"""Maps of new sites: incremental grid mapping by scan matching, and mapping with people filtered out."""
