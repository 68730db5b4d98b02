// vent grille: a 40 x 28 mm frame 3 mm thick and 5 mm tall with seven 1 mm louvres
union() {
  difference() {
    translate([-20, -14, 0]) cube([40, 28, 5]);
    translate([-17, -11, -1]) cube([34, 22, 7]);
  }
  for (i = [0:6]) translate([-15 + 5 * i, -11.5, 0]) cube([1, 23, 5]);
}
