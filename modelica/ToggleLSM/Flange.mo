within ToggleLSM;
connector Flange "One-dimensional translational flange along the x axis"
  Real s(unit = "m") "Absolute position of the flange";
  flow Real f(unit = "N") "Cut force acting on the component at this flange, positive along +x";
end Flange;
