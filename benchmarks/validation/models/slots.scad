// slotted plate: a 40 x 24 x 4 mm plate with five 2 mm slots 16 mm long (rounded ends)
difference() {
  translate([-20, -12, 0]) cube([40, 24, 4]);
  for (i = [0:4]) translate([-14 + 7 * i, 0, -1]) hull() {
    translate([0, -7, 0]) cylinder(h = 6, r = 1, $fn = 24);
    translate([0, 7, 0]) cylinder(h = 6, r = 1, $fn = 24);
  }
}
