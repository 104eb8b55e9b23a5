within ;
package ToggleLSM "Toggle mechanism driven by a permanent-magnet linear synchronous motor (Fung, Wu and Chen 2001)"
  /* One class per file, in the order of package.order:
       Flange                  a 1-D translational connector (position, cut force)
       LinearSynchronousMotor  PMLSM field and thrust, eqs. (1)-(16), and the drive's current loop
       ToggleMechanism         the Lagrange-multiplier DAE with joint Coulomb friction, eqs. (17)-(18)
       LoadForce               the external force F_E on slider B
       Plant                   the three connected; the FMU's interface contract
     Values marked "assumed" are not in the paper (its mechanism data come from its
     reference [8], not available to us); docs/model.md says why each was chosen. */
end ToggleLSM;
