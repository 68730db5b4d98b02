// tube bundle: seven 4 mm tubes (0.9 mm walls, 9 mm tall) on a hexagonal 6 mm grid, no base
for (p = [[0, 0], [6, 0], [-6, 0], [3, 5.2], [-3, 5.2], [3, -5.2], [-3, -5.2]])
  translate([p[0], p[1], 0]) difference() {
    cylinder(h = 9, r = 2, $fn = 48);
    translate([0, 0, -1]) cylinder(h = 11, r = 1.1, $fn = 48);
  }
