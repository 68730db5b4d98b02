// peg board: a 36 x 36 x 1.5 mm plate with a 4 x 4 grid of pegs, 3 mm across and 6 mm tall
union() {
  translate([-18, -18, 0]) cube([36, 36, 1.5]);
  for (i = [0:3], j = [0:3]) translate([-12 + 8 * i, -12 + 8 * j, 0])
    cylinder(h = 7.5, r = 1.5, $fn = 24);
}
