// lattice block: a 40 x 30 x 6 mm block with a 6 x 4 grid of 4 mm square holes (short bars)
difference() {
  translate([-20, -15, 0]) cube([40, 30, 6]);
  for (i = [0:5], j = [0:3]) translate([-17 + 6 * i, -12 + 6.5 * j, -1]) cube([4, 4, 8]);
}
