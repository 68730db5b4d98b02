// hex nut: 24 mm across corners, 8 mm high, a 10 mm bore and a chamfered top
difference() {
  intersection() {
    cylinder(h = 8, r = 12, $fn = 6);
    cylinder(h = 8, r1 = 14, r2 = 9.5, $fn = 60);
  }
  translate([0, 0, -1]) cylinder(h = 10, r = 5, $fn = 48);
}
