"""Sea maps and the planning chain (Ljungberg 2022, chapters 7-8, section 9.4).

geo (load/validate/project GeoJSON -> SeaMap, MapError), trialdesign (design of the ship's
library rounded to whole manoeuvres, redesign without what fits nowhere), motionset and lattice
(moves settled onto the lattice, run-ins, the helm for azimuth and rudder ships), collision
(conservative raster checks), astar (search and heuristics), smooth (legs, closed-loop
realisation, straightened transit), verify (continuous re-simulation), chain (the steps one at a
time), planner (``plan_trial -> Plan``), scenario (section 9.4 primitives), testmaps (synthetic
fjord, archipelago, open sea), output (plan.json, trajectory.geojson, picture), plan (the Plan
read by the exporters).
"""
