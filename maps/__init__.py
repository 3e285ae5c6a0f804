"""Sea maps and the A* lattice planner (seed 001 chapter 8, section 9.4).

geo (load/validate/project GeoJSON -> SeaMap, MapError), collision (conservative raster checks),
lattice (motion set settled onto the lattice), astar (search and heuristics), verify
(continuous re-simulation), planner (``plan_trial -> Plan``), scenario (section 9.4 primitives),
output (plan.json, trajectory.geojson, picture), plan (the Plan read by the exporters).
"""
