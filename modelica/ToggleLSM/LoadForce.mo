within ToggleLSM;
model LoadForce "External force F_E on slider B; F_E >= 0 resists the forward stroke (+x)"
  input Real F_E(unit = "N") "External force, positive against the forward stroke";
  Flange flange "Connected to slider B";
equation
  flange.f = F_E;
end LoadForce;
