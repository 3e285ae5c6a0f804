"""A first manoeuvring model of a ship from its main particulars (length, beam, draught, block
coefficient, rudder, propeller, speed): published regressions give an MMG standard model
(Yasukawa & Yoshimura 2015), which is simulated and fitted into a profile's per-sample form."""
