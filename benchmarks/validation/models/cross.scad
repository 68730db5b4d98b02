// cross: two 36 mm arms 1.2 mm thick crossing at the middle, 7 mm tall, on a 1 mm disc
union() {
  cylinder(h = 1, r = 10, $fn = 72);
  translate([-18, -0.6, 0]) cube([36, 1.2, 7]);
  translate([-0.6, -18, 0]) cube([1.2, 36, 7]);
}
