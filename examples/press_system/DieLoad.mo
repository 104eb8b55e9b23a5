model DieLoad "Die contact force on slider B: a linear spring that acts once slider B passes the contact position"
  parameter Real x_c(unit = "m") = 0.31 "Contact position of the die";
  parameter Real k_c(unit = "N/m") = 1e4 "Contact stiffness of the die (99 N at the stroke's end with x_c = 0.31 m)";
  input Real x(unit = "m") "Position of slider B (the plant's x_B)";
  output Real F(unit = "N") "Contact force on slider B, >= 0 resists the forward stroke (the plant's F_E)";
equation
  F = k_c * max(x - x_c, 0.0);
end DieLoad;
