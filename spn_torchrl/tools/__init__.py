"""Working with an evolved SPN: load a run's elite (elite), replay it (play), draw it (pictures), export it."""
