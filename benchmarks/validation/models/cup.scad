// tapered cup: a 1.2 mm wall flaring from r 10 to r 14 over 14 mm on a 1 mm floor
difference() {
  cylinder(h = 14, r1 = 10, r2 = 14, $fn = 96);
  translate([0, 0, 1]) cylinder(h = 14, r1 = 8.8, r2 = 12.8, $fn = 96);
}
