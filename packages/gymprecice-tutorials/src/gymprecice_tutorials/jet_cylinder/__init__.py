"""JetCylinder-v0 (see :mod:`.environment`); kept empty so importing geometry stays light."""
