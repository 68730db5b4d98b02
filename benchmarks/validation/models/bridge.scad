// bridge: two 6 x 10 mm pillars 8 mm tall joined by a 2 mm deck spanning 20 mm between them
union() {
  translate([-16, -5, 0]) cube([6, 10, 10]);
  translate([10, -5, 0]) cube([6, 10, 10]);
  translate([-16, -5, 8]) cube([32, 10, 2]);
}
