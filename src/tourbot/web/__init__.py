"""Web tele-presence (Burgard et al., section 6): control slots, the live stream, the site database,
the visitor, on-board and admin pages."""
