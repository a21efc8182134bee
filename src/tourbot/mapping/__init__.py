"""Mapping: incremental scan-matching grid mapping (Eq. 1-2), people-filtered mapping (Eq. 10),
ego-motion by scan matching, and the relative pose error."""
