// perforated plate: 5 x 4 round holes in a 2.4 mm plate (many small perimeters, retractions)
difference() {
  translate([-30, -22, 0]) cube([60, 44, 2.4]);
  for (i = [0:4], j = [0:3]) translate([-24 + 12 * i, -15 + 10 * j, -1])
    cylinder(h = 5, r = 2.5 + 0.5 * ((i + j) % 3), $fn = 36);
}
