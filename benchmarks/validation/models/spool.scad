// spool: a 10 mm hub with a 4 mm bore between two 30 mm flanges 1.2 mm thick
difference() {
  union() {
    cylinder(h = 1.2, r = 15, $fn = 90);
    cylinder(h = 9, r = 5, $fn = 60);
    translate([0, 0, 7.8]) cylinder(h = 1.2, r = 15, $fn = 90);
  }
  translate([0, 0, -1]) cylinder(h = 11, r = 2, $fn = 30);
}
